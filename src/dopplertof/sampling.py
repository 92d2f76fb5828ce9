"""Time sampling and correlated random streams (design.md section 2).

A pixel's samples come in groups of K that share a time stream, and in *path groups*
of Kp consecutive samples (``path_correlate_number``, default K) that share a path
stream. Every random number is a function of (seed, pixel, stream, dimension), never
drawn from a sequential generator: a hash of them for the *shared* stream of a group
(keyed by the group index) or the sample's *own* stream (keyed by its global sample
index); the film position, the time and the first hit's light and BSDF samples are
points of the pixel's low-discrepancy sets instead (scrambled Sobol sequences, a shifted
lattice for the BSDF sample; indexed by the sample's number in the pixel, see
:meth:`CorrelatedStreams.film_2d`). Stage ``k`` of a path (0: camera
ray; k >= 1: the decisions at the k-th surface hit) draws from its path group's shared
stream when ``k < path_correlation_depth``. Because dimensions are fixed per stage,
the two streams stay aligned whatever is selected, and a sample replays exactly for
the same pixel, sample index and dimension, whatever the pass it is rendered in.

All functions work on Dr.Jit arrays of the current Mitsuba variant.
"""

from __future__ import annotations

import enum

from .pixel_sets import JointSets
from .sequences import (KEY_ROUNDS, decision_2d, hashed_uniform, mix32, owen_sobol,
                        pixel_stream_key, reverse_permute, sobol_2d, sobol_component, tagged,
                        unit_float)


class TimeSampling(str, enum.Enum):
    """The ``time_sampling_method`` names: the vocabulary of renderer, analysis,
    experiments and benchmarks (a ``str``: members compare equal to their names)."""

    UNIFORM = "uniform"  #: t = T u per sample
    STRATIFIED = "stratified"  #: t_i = T (i + u_i) / K
    ANTITHETIC = "antithetic"  #: shifted: t_i = T frac(u + i a) (a = 1/K for K > 2)
    ANTITHETIC_MIRROR = "antithetic_mirror"  #: t_1 = T frac(1 - u + a)
    ANALYTIC = "analytic"  #: integrated over the exposure (integrators/analytic.py; biased)
    #: the analytic integral as a control variate for one sampled time per path (unbiased;
    #: integrators/control_variate.py)
    CONTROL_VARIATE = "control_variate"
    AUTO = "auto"  #: chosen from the beat count (:func:`auto_sampling`)

    @property
    def index(self) -> int:
        """The kernel's number for a sampled method (its position in METHODS)."""
        return method_index(self.value)


#: the sampled methods, in the kernel's order (``time_fraction``'s ``method``)
METHODS = tuple(m.value for m in (TimeSampling.UNIFORM, TimeSampling.STRATIFIED,
                                  TimeSampling.ANTITHETIC, TimeSampling.ANTITHETIC_MIRROR))

#: time integrated over the exposure, not sampled (integrators/analytic.py; biased)
ANALYTIC = TimeSampling.ANALYTIC.value

#: the analytic integral as a control variate (integrators/control_variate.py; unbiased)
CONTROL_VARIATE = TimeSampling.CONTROL_VARIATE.value

#: the methods built on the closed-form time integral of a low-pass sinusoid
CLOSED_FORM = (ANALYTIC, CONTROL_VARIATE)

#: accepted time_sampling_method names: the methods, ``analytic`` and ``auto``
METHOD_NAMES = tuple(m.value for m in TimeSampling)

#: path_correlation_depth meaning "the whole path" (more stages than any path has)
FULL_CORRELATION = 1 << 16

#: how an antithetic pair's partner is built (integrators/antithetic_map.py)
ANTITHETIC_MAPPINGS = ("replay", "motion")

# ---- Dimension layout -------------------------------------------------------
# The path loop's own numbers; a modality's own (what it reads beyond the loop's) go in
# the slots reserved for modalities, placed by its ModalityDimensions.
DIM_TIME = 0  #: the time sample
DIM_WAVELENGTH = 1  #: the wavelengths of the path (spectral variants)
# (film positions come from CorrelatedStreams.film_2d)
DIM_MODALITY_LANE = 2  #: the first of a lane's numbers reserved for its modality
MODALITY_LANE_DIMS = 2  #: how many: dimensions 2 and 3
DIM_APERTURE = 4  #: lens position (2 numbers)
DIM_FIRST_BOUNCE = 6  #: the first surface hit's decisions start here
DIMS_PER_BOUNCE = 8  #: emitter sample (2), BSDF sample (1 + 2), Russian roulette (1), modality (2)

# Offsets within a bounce's block of dimensions.
BOUNCE_EMITTER = 0
BOUNCE_BSDF_LOBE = 2
BOUNCE_BSDF_DIR = 3
BOUNCE_RR = 5
BOUNCE_MODALITY = 6  #: the first of a bounce's numbers reserved for the modality
MODALITY_BOUNCE_DIMS = 2  #: how many: offsets 6 and 7


class ModalityDimensions:
    """The random numbers a modality reads of its own, each group by name with its
    count: ``lane`` once per lane (stage 0, the camera ray's stream), ``bounce`` at
    every surface hit (that hit's stage). Placed in declaration order in the slots the
    layout reserves (DIM_MODALITY_LANE, BOUNCE_MODALITY), so that a modality's numbers
    never coincide with the path loop's; a declaration that does not fit is refused
    when it is made. The D-ToF camera reads none."""

    def __init__(self, lane: tuple = (), bounce: tuple = ()):
        self.lane = _placed(lane, DIM_MODALITY_LANE, MODALITY_LANE_DIMS, "lane")
        self.bounce = _placed(bounce, BOUNCE_MODALITY, MODALITY_BOUNCE_DIMS, "bounce")

    def lane_dim(self, name: str) -> int:
        """The first dimension of the lane's numbers ``name``."""
        return self.lane[name]

    def bounce_dim(self, depth, name: str, k: int = 0):
        """Dimension of number ``k`` of the group ``name`` at surface hit ``depth``."""
        return bounce_dim(depth, self.bounce[name] + k)


def _placed(groups: tuple, first: int, room: int, what: str) -> dict:
    """{name: its first dimension} of ``groups`` ((name, count), ...) laid out from
    ``first``, a ValueError beyond ``room`` numbers."""
    placed, at = {}, first
    for name, count in groups:
        placed[name], at = at, at + count
    if at - first > room:
        raise ValueError(f"a modality's {what} numbers {dict(groups)} need {at - first} "
                         f"dimensions; the layout reserves {room}")
    return placed


# TEA rounds: KEY_ROUNDS (sequences.py) to derive a lane's stream keys (once per path)
# and 6 for its time numbers; the many numbers along a path use the cheaper integer hash.
_NUMBER_ROUNDS = 6


def _hop_tag(mi, hop, k: int):
    """Tag k of a joint-set hop (int or per lane) as a 32-bit word."""
    tag = (hop * 4 + k + 16) * 0x9E3779B9
    return mi.UInt32(tag & 0xFFFFFFFF) if isinstance(hop, int) else tag


#: largest sample count per pixel the 32-bit stream keys allow
MAX_SPP = 1 << 30

#: seeds are the integers in [0, SEED_LIMIT): all 64 bits key the streams (seed_words)
SEED_LIMIT = 1 << 64


def seed_words(seed: int) -> tuple:
    """The stream key of a seed in [0, 2^64): its (low, high) 32-bit words, the one map
    from a seed to what the kernel reads (``high`` is None below 2^32). Distinct seeds
    give distinct words: comparing them compares what the streams are keyed by."""
    seed = int(seed)
    if not 0 <= seed < SEED_LIMIT:
        raise ValueError(f"seed must be an integer in [0, 2^64), got {seed}")
    high = seed >> 32
    return seed & 0xFFFFFFFF, (high or None)


def method_index(name: str) -> int:
    try:
        return METHODS.index(name)
    except ValueError:
        raise ValueError(
            f"unknown time_sampling_method {name!r}: expected one of {', '.join(METHODS)}"
        ) from None


#: |h - n| (beats per exposure from the nearest integer n >= 1) within which antithetic
#: pairs beat the control variate (benchmarks/control_variate.py --beats)
PAIRS_WINDOW = 0.08
#: the fewest beats per exposure at which the control variate beats stratified time
CONTROL_VARIATE_BEATS = 0.5


def auto_sampling(hetero_frequency: float, closed_form: bool = False) -> dict:
    """The sampling ``time_sampling_method="auto"`` stands for, given h = omega_d T / 2 pi
    and whether the control variate may serve (``closed_form``: a low-pass sinusoid, a
    render whose derivatives are not taken).

    Antithetic pairs with the whole path shared cancel a beat of the heterodyne signal
    when the pair is half a beat apart: near an integer number n >= 1 of beats per
    exposure the shift 1/(2n) (exactly 1/2 at n = 1) makes the pair's time signals
    cancel (supplementary section 3). Elsewhere a beat left in the samples dominates
    their variance, and the analytic integral as a control variate
    (integrators/control_variate.py), which carries the beat in its model, does better
    from half a beat on in spite of its three paths per sample: on the published
    Cornell box at equal time against the better of pairs and stratified time, 1.4x at
    h = 0.5, 2.1x at 0.75, 1.6x at 2.1, 6.6x at 1.5, 17x at 3.5, even at 1.08, but
    0.18x at h = 1, 0.32x at 1.05 and 0.23x at 2, where pairs cancel the beat
    (docs/benchmarks.md). Below half a beat, and at h = 0 where a pair only duplicates
    a path (a loss of sqrt 2), independent paths with a group's K times in the K parts
    of the exposure, the strata spread over a pixel's groups, do best. The group size K
    (``time_correlate_number``) stays the user's: K > 2 antithetic groups are
    periodic, and cancel a beat as pairs do unless n is a multiple of K.
    Without the control variate (other waveforms, derivatives) pairs keep the window of
    0.3 measured against stratified time (ratio 9.1 against 5.0 at h = 0.75).
    """
    h = abs(hetero_frequency)
    n = round(h)
    window = PAIRS_WINDOW if closed_form else 0.3
    if n >= 1 and abs(h - n) <= window:
        return dict(time_sampling_method="antithetic", antithetic_shift=0.5 / n,
                    path_correlation_depth=FULL_CORRELATION,
                    use_stratified_sampling_for_each_interval=True,
                    antithetic_mapping="replay")
    if closed_form and h >= CONTROL_VARIATE_BEATS:
        return dict(time_sampling_method=CONTROL_VARIATE, path_correlation_depth=0,
                    use_stratified_sampling_for_each_interval=True,
                    antithetic_mapping="replay")
    return dict(time_sampling_method="stratified", path_correlation_depth=0,
                use_stratified_sampling_for_each_interval=True,
                antithetic_mapping="replay")


def bounce_dim(depth, offset: int):
    """Dimension of a decision at surface hit ``depth`` (0-based)."""
    return DIM_FIRST_BOUNCE + DIMS_PER_BOUNCE * depth + offset


class CorrelatedStreams:
    """The shared and own random streams of a set of lanes.

    Parameters are Dr.Jit UInt32 arrays (one entry per lane) except ``seed`` and
    ``correlation_depth``, which may be opaque scalars. ``group`` keys the time
    stream (``key_group``), ``path_group`` (default: ``group``) the shared path stream
    (``key_path``); with Kp = K they are one stream, as published. ``seed`` and
    ``seed_high`` are the words of :func:`seed_words` (``seed_high`` None below 2^32).
    """

    def __init__(self, mi, pixel, group, sample, seed, correlation_depth, path_group=None,
                 seed_high=None, joint: JointSets | None = None):
        self.mi = mi
        self.base = pixel_stream_key(mi, pixel, seed, seed_high)
        base = self.base
        #: the tile's sequence for film, time and first hit (None: the pixel's own sets)
        self.joint = joint
        self.joint_keys = (None if joint is None
                           else joint.lane_keys(mi, pixel, seed, seed_high, base))
        self.key_group, _ = mi.sample_tea_32(base, group * 2, KEY_ROUNDS)
        self.path_group = group if path_group is None else path_group
        self.key_path = (self.key_group if path_group is None
                         else mi.sample_tea_32(base, path_group * 2, KEY_ROUNDS)[0])
        self.key_own, _ = mi.sample_tea_32(base, sample * 2 + 1, KEY_ROUNDS)
        self.correlation_depth = correlation_depth
        if joint is not None:  # the lane's points in its tile: own and its path group's
            index_in_group = sample - group * joint.K
            self.joint_own, self.joint_path = (
                joint.locate(mi, self.joint_keys, kind, group, index_in_group,
                             self.path_group) for kind in ("sample", "path"))
            self.joint_pilot = (group < joint.pilot // joint.K if joint.pilot
                                else mi.Bool(False))

    def _pixel_seed(self, tag: int):
        """A per-pixel scramble seed: the pixel's key hashed with a tag (one cheap hash;
        the TEA rounds went into the key)."""
        return tagged(self.base, tag)

    def key(self, stage):
        """The stream key of a sampling stage (0: camera, k: k-th surface hit)."""
        import drjit as dr

        return dr.select(stage < self.correlation_depth, self.key_path, self.key_own)

    def get_1d(self, stage, dim):
        return hashed_uniform(self.mi, self.key(stage), self.mi.UInt32(dim))

    def sequence_index(self, group, index_in_group, groups_per_pixel: int):
        """A sample's index in the pixel's low-discrepancy sequence: its path group when
        the camera ray is shared (stage 0 correlated); else its index taken index-major
        (i * G + g), so that the sequence's leading digits, which set the coarse
        position, follow the group and not the index in the group, which the stratified
        method ties to the time."""
        import drjit as dr

        shared = self.correlation_depth > 0
        return dr.select(shared, self.path_group,
                         index_major(self.mi, index_in_group, groups_per_pixel, group))

    def film_2d(self, group, index_in_group, groups_per_pixel: int):
        """Film position: Sobol's first two dimensions (a scrambled (0,2)-sequence) at
        the sample's sequence index."""
        if self.joint is not None:
            return self._joint_film()
        index = self.sequence_index(group, index_in_group, groups_per_pixel)
        shift_x, shift_y = self._pixel_seed(1), self._pixel_seed(2)
        return sobol_2d(self.mi, index, shift_x, shift_y)

    def _joint_film(self):
        """Film position from the image's net (pixel_sets="joint"): the point's digits
        below the pixel's, Owen-scrambled (the pixel's digits kept: the scramble is
        nested, so the net stays one), as a position in the pixel."""
        import drjit as dr

        mi, joint = self.mi, self.joint
        _, _, index, key = self._lane_point(0)
        levels = joint.image_levels or 0
        top = mi.UInt32((0xFFFFFFFF << (32 - levels)) & 0xFFFFFFFF if levels else 0)
        keep = dr.select(self.joint_pilot, 0, top)  # the pilot: the pixel's own sequence
        shift = dr.select(self.joint_pilot, 0, levels)
        position = []
        for d in (0, 1):
            value = sobol_component(mi, index, d, 0)
            scrambled = (value & keep) | (reverse_permute(mi, value, tagged(key, 1 + d))
                                         & ~keep)
            position.append(unit_float(mi, scrambled << shift))
        return mi.Point2f(*position)

    def _lane_point(self, stage):
        """The lane's point and key in its tile for sampling ``stage``: its path
        group's when the stage is shared, else its own."""
        import drjit as dr

        shared = stage < self.correlation_depth
        return tuple(dr.select(shared, a, b) for a, b in zip(self.joint_path, self.joint_own))

    def joint_decision(self, depth, which: int):
        """A 2-D decision at surface hit ``depth`` (0-based; int or per lane; ``which``
        0: the light sample, 1: the BSDF sample) from the tile's joint sets
        (pixel_sets="joint"), at the lane's point shuffled per decision (decisions
        paired at random, not by index): for a light sample Sobol's (0,2)-sequence, its
        values Owen-scrambled; for a BSDF sample the shifted lattice sequence
        (:func:`lattice_2d`; a pixel's block of it, and every 2x2, 4x4, ... block of
        pixels' in Z order, is a lattice shifted on the torus). The first hit's light
        sample comes from :meth:`first_hit_2d` instead."""
        mi = self.mi
        point, key = self._lane_point(depth + 1)[:2]
        hop = depth * 2 + which
        seed_index, seed_x, seed_y = (mix32(key ^ _hop_tag(mi, hop, k)) for k in range(3))
        return decision_2d(mi, reverse_permute(mi, point, seed_index), which, seed_x, seed_y)

    def _joint_first_light(self):
        """The first hit's light sample with joint sets: Sobol's dimensions 3 and 4 at
        the film position's index in the image's net, so that film position and light
        sample form one 4-D set over the image: a splat weighs a pixel's samples by
        their film positions, and samples of similar weight then still stratify the
        light (3.3x less variance with a tent on direct light, docs/benchmarks.md)."""
        mi = self.mi
        film_index, film_key = self._lane_point(1)[2:]
        return mi.Point2f(*(unit_float(mi, owen_sobol(mi, film_index, d, tagged(film_key, 5 + d)))
                            for d in (3, 4)))

    def joint_point(self, shared, kind_if_shared: str, group, index_in_group):
        """The tile's point and scramble key for one of the pixel's sets: by the
        ``kind_if_shared`` group ("path" or "group") where ``shared``, else
        index-major (:meth:`JointSets.locate`)."""
        import drjit as dr

        joint, keys = self.joint, self.joint_keys
        own = joint.locate(self.mi, keys, "sample", group, index_in_group, self.path_group)
        by_group = joint.locate(self.mi, keys, kind_if_shared, group, index_in_group,
                                self.path_group)
        return tuple(dr.select(shared, a, b) for a, b in zip(by_group, own))

    def time_sequence(self, index, double: bool):
        """Sobol's third dimension at ``index``, Owen-scrambled per pixel: with the
        film position of the same index, (film, time) is a (1,3)-sequence, so that a
        pixel's samples stratify the film and the exposure jointly (what a silhouette
        moving across the pixel needs)."""
        mi = self.mi
        seed = self._pixel_seed(3)
        if isinstance(index, tuple):  # joint sets: the film's index in the image's net
            index, seed = index[2], tagged(index[3], 3)
        # Owen scrambling, not a digital shift: a shift keeps the points' fine digits in
        # a fixed pattern, which aliases with a full waveform's 10^4-10^5 periods
        bits = owen_sobol(mi, index, 2, seed)
        if not double:
            return unit_float(mi, bits)
        # 32 bits, and the low-order bits filled at random (full-waveform phases)
        low = hashed_uniform(mi, self.base ^ bits, mi.UInt32(DIM_TIME))
        return (mi.Float64(bits) + mi.Float64(low)) * (1.0 / (1 << 32))

    def first_hit_2d(self, dim: int, group, index_in_group, groups_per_pixel: int):
        """The first surface hit's 2-D decision ``dim`` (0: the light sample, 1: the
        BSDF sample) from the pixel's own low-discrepancy set, at an index shuffled per
        dimension (so that film, time and each decision are paired at random, not by
        index): for the light sample Sobol's (0,2)-sequence, its values Owen-scrambled;
        for the BSDF sample the shifted rank-1 lattice sequence (:func:`lattice_2d`),
        whose even spread suits the directions of the first bounce. The index is the
        path group's when stage 1 is shared."""
        import drjit as dr

        mi = self.mi
        if self.joint is not None:
            return self._joint_first_light() if dim == 0 else self.joint_decision(0, 1)
        index = dr.select(1 < self.correlation_depth, self.path_group,
                          index_major(mi, index_in_group, groups_per_pixel, group))
        seed_index, seed_x, seed_y = (self._pixel_seed(4 + 3 * dim + k) for k in range(3))
        return decision_2d(mi, reverse_permute(mi, index, seed_index), dim, seed_x, seed_y)

    def get_2d(self, stage, dim):
        key = self.key(stage)
        dim = self.mi.UInt32(dim)
        return self.mi.Point2f(hashed_uniform(self.mi, key, dim),
                               hashed_uniform(self.mi, key, dim + 1))


def index_major(mi, index_in_group, groups_per_pixel: int, group):
    """A sample's index-major index in its pixel's sequence, i * G + g, with the
    render's G (groups per pixel, from its spp) an opaque value: one kernel serves every
    spp."""
    import drjit as dr

    return index_in_group * dr.opaque(mi.UInt32, groups_per_pixel) + group


def time_fraction(mi, streams: CorrelatedStreams, group, index, *, group_size: int,
                  groups_per_pixel: int, method, antithetic_shift, stratify: bool,
                  double: bool):
    """Sample time as a fraction of the exposure, in [0, 1), per lane.

    ``method`` (an index into METHODS) and ``antithetic_shift`` may be opaque
    JIT scalars, so that one compiled kernel serves every method. ``double``
    returns Float64 (full-waveform mode needs time resolved far below one period
    of the modulation).
    """
    import drjit as dr

    Float = mi.Float64 if double else mi.Float
    sample = mi.sample_tea_float64 if double else mi.sample_tea_float32
    K = group_size

    # ---- Primal numbers: one per group (antithetic) or per sample (others) ----
    is_antithetic = method >= TimeSampling.ANTITHETIC.index  # (and mirrored)
    if stratify and groups_per_pixel > 1:
        # Full time stratification across the groups of a pixel: the pixel's Sobol
        # sequence, per group for antithetic pairs (the group's film index when the
        # camera ray is shared), else per sample, index-major (the film index when it
        # is not).
        if streams.joint is not None:  # the tile's sequence: per group or index-major
            located = streams.joint_point(is_antithetic, "group", group, index)
        else:
            located = dr.select(is_antithetic, group,
                                index_major(mi, index, groups_per_pixel, group))
        u = streams.time_sequence(located, double)
    else:
        u = dr.select(is_antithetic,
                      sample(streams.key_group, DIM_TIME, _NUMBER_ROUNDS),
                      sample(streams.key_own, DIM_TIME, _NUMBER_ROUNDS))

    # ---- The four methods ----
    fi = Float(index)
    t_uniform = u
    t_stratified = (fi + u) * (1.0 / K)
    shift = Float(antithetic_shift) if K == 2 else Float(1.0 / K)
    t_shifted = u + fi * shift
    t_shifted -= dr.floor(t_shifted)
    t_mirror = dr.select(index == 0, u, 1.0 - u + Float(antithetic_shift))
    t_mirror -= dr.floor(t_mirror)

    t = dr.select(method == TimeSampling.UNIFORM.index, t_uniform, t_stratified)
    t = dr.select(method == TimeSampling.ANTITHETIC.index, t_shifted, t)
    t = dr.select(method == TimeSampling.ANTITHETIC_MIRROR.index, t_mirror, t)
    return t


def check_sample_count(group_size: int, spp: int, path_group_size: int | None = None,
                       samples_per_pass: int = -1) -> None:
    """Errors for a sample count that the correlated groups (K samples sharing a time
    stream, Kp a path stream) or the published ``samples_per_pass`` cannot use."""
    if spp < 1:
        raise ValueError(f"spp must be >= 1, got {spp}")
    if spp > MAX_SPP:
        raise ValueError(f"spp {spp} exceeds the supported maximum {MAX_SPP}")
    if spp % group_size != 0:
        raise ValueError(
            f"spp {spp} is not a multiple of the group size time_correlate_number={group_size}"
        )
    if path_group_size is not None and spp % path_group_size != 0:
        raise ValueError(
            f"spp {spp} is not a multiple of path_correlate_number={path_group_size} "
            "(samples sharing one path stream)")
    if samples_per_pass > 0 and spp % samples_per_pass != 0:
        raise ValueError(
            f"spp {spp} is not a multiple of samples_per_pass={samples_per_pass}")


__all__ = [
    "FULL_CORRELATION",
    "METHODS",
    "TimeSampling",
    "CorrelatedStreams",
    "time_fraction",
    "method_index",
    "check_sample_count",
    "bounce_dim",
    "seed_words",
    "SEED_LIMIT",
]
