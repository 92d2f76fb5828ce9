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


class TimeSampling(str, enum.Enum):
    """The ``time_sampling_method`` names: the vocabulary of renderer, analysis,
    experiments and benchmarks (a ``str``: members compare equal to their names)."""

    UNIFORM = "uniform"  #: t = T u per sample
    STRATIFIED = "stratified"  #: t_i = T (i + u_i) / K
    ANTITHETIC = "antithetic"  #: shifted: t_i = T frac(u + i a) (a = 1/K for K > 2)
    ANTITHETIC_MIRROR = "antithetic_mirror"  #: t_1 = T frac(1 - u + a)
    ANALYTIC = "analytic"  #: integrated over the exposure (integrators/analytic.py; biased)
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

#: accepted time_sampling_method names: the methods, ``analytic`` and ``auto``
METHOD_NAMES = tuple(m.value for m in TimeSampling)

#: path_correlation_depth meaning "the whole path" (more stages than any path has)
FULL_CORRELATION = 1 << 16

#: how an antithetic pair's partner is built (integrators/antithetic_map.py)
ANTITHETIC_MAPPINGS = ("replay", "motion")

# ---- Dimension layout -------------------------------------------------------
DIM_TIME = 0  #: the time sample
DIM_WAVELENGTH = 1  #: the wavelengths of the path (spectral variants)
# (film positions come from CorrelatedStreams.film_2d; the D-ToF renders leave 2 and 3 free)
DIM_BEAM_FILM = 2  #: FMCW's collimated beam: its spot's film position (2 numbers; issue 43)
DIM_APERTURE = 4  #: lens position (2 numbers)
DIM_FIRST_BOUNCE = 6  #: the first surface hit's decisions start here
DIMS_PER_BOUNCE = 8  #: emitter sample (2), BSDF sample (1 + 2), Russian roulette (1), spare (2)

# Offsets within a bounce's block of dimensions.
BOUNCE_EMITTER = 0
BOUNCE_BSDF_LOBE = 2
BOUNCE_BSDF_DIR = 3
BOUNCE_RR = 5
BOUNCE_SPARE = 6  #: the two spare numbers (FMCW's speckle phases; issue 43)

# TEA rounds: 8 to derive a lane's stream keys (once per path) and 6 for its time
# numbers; the many numbers along a path use the cheaper integer hash below.
_KEY_ROUNDS = 8
_NUMBER_ROUNDS = 6


def _mix32(x):
    """A 32-bit integer hash with full avalanche (multiply-xorshift, two rounds)."""
    x = x ^ (x >> 16)
    x = x * 0x7FEB352D
    x = x ^ (x >> 15)
    x = x * 0x846CA68B
    return x ^ (x >> 16)


def _tagged(key, tag: int):
    """A scramble seed from a stream key and a tag (one cheap hash)."""
    return _mix32(key ^ ((tag * 0x9E3779B9) & 0xFFFFFFFF))


def _gf2_inverse_columns(columns, bits: int) -> list:
    """The columns of the inverse of a ``bits`` x ``bits`` matrix over GF(2) given by its
    columns (integers, bit r: row r): entry r solves B z = e_r (z: bit j for column j)."""
    basis = {}  # leading bit -> (value, the columns it sums)
    for j, column in enumerate(columns):
        value, combination = column, 1 << j
        for bit in reversed(range(bits)):
            if (value >> bit) & 1:
                if bit not in basis:
                    basis[bit] = (value, combination)
                    break
                value ^= basis[bit][0]
                combination ^= basis[bit][1]
    if len(basis) != bits:
        raise ValueError("the film net's generator block is singular")
    inverse = []
    for r in range(bits):
        value, combination = 1 << r, 0
        for bit in reversed(range(bits)):
            if (value >> bit) & 1:
                value ^= basis[bit][0]
                combination ^= basis[bit][1]
        inverse.append(combination)
    return inverse


def _hop_tag(mi, hop, k: int):
    """Tag k of a joint-set hop (int or per lane) as a 32-bit word."""
    tag = (hop * 4 + k + 16) * 0x9E3779B9
    return mi.UInt32(tag & 0xFFFFFFFF) if isinstance(hop, int) else tag


def hashed_uniform(mi, key, dim):
    """Uniform number in [0, 1) for a stream key and a dimension: two hash rounds, the
    dimension spread first so that consecutive dimensions are unrelated."""
    x = _mix32(key ^ _mix32(dim * 0x9E3779B9 + 0x7F4A7C15))
    return mi.Float(x >> 8) * (1.0 / (1 << 24))  # 24 bits: exact and below 1

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


def _pixel_key(mi, pixel, seed_low, seed_high):
    """A pixel's 32-bit key, from which all its streams derive: TEA of (pixel, low
    word), and for a seed of 2^32 or more that key encrypted once more with the high
    word as the second half of the block.

    Seeds below 2^32 (``seed_high`` None) keep the one TEA they always had: their images
    are bitwise unchanged. Folding the high word into the low one (low ^ f(high)) would
    alias seed low ^ f(high) exactly; the second encryption cannot: its block (first
    key, high word) differs at every pixel, and two seeds give the same image only if
    their keys agree at every pixel of the film. A key is half of a TEA block (8 rounds
    of a Feistel cipher, a bijection of 64-bit blocks), so the keys of two seeds agree
    at a pixel by chance only, 2^-32, independently over the pixels: over N pixels a
    pair of seeds aliases with chance 2^-32N, and any of the 2^32 seeds below 2^32
    aliases a given large seed with chance 2^(32 - 32N), at most 2^-96 for films of 4
    pixels or more: the odds two seeds below 2^32 have always had. (A one-pixel film
    has only 2^32 keys: seeds alias there by counting, whatever the hash.)
    tests/test_sampling.py checks 2^32, 2^32 + 1, 2^40 and 2^64 - 1 against seeds 0, 1
    and each other."""
    key, _ = mi.sample_tea_32(pixel, seed_low, _KEY_ROUNDS)
    if seed_high is None:
        return key
    key, _ = mi.sample_tea_32(key, seed_high, _KEY_ROUNDS)
    return key


def method_index(name: str) -> int:
    try:
        return METHODS.index(name)
    except ValueError:
        raise ValueError(
            f"unknown time_sampling_method {name!r}: expected one of {', '.join(METHODS)}"
        ) from None


def auto_sampling(hetero_frequency: float) -> dict:
    """The sampling ``time_sampling_method="auto"`` stands for, given h = omega_d T / 2 pi.

    Antithetic pairs with the whole path shared cancel a beat of the heterodyne signal
    when the pair is half a beat apart: near an integer number n >= 1 of beats per
    exposure the shift 1/(2n) (exactly 1/2 at n = 1) makes the pair's time signals
    cancel (supplementary section 3; the published Cornell box: RMSE ratio about 32 at
    h = 1; 9.1 against 5.0 for the alternative at h = 0.75, hence the window of 0.3).
    Far from an integer, and at h = 0 where a pair only duplicates a path (a loss of
    sqrt 2), correlated pairs do not pay: independent paths, a group's K times in the K
    parts of the exposure and the strata spread over a pixel's groups, do
    better (ratio 4.6 at h = 0.5, 3.1 at h = 0.25, 1.0 at h = 0; docs/benchmarks.md).
    The group size K (``time_correlate_number``) stays the user's: K > 2 antithetic
    groups are periodic, and cancel a beat as pairs do unless n is a multiple of K.
    """
    h = abs(hetero_frequency)
    n = round(h)
    if n >= 1 and abs(h - n) <= 0.3:
        return dict(time_sampling_method="antithetic", antithetic_shift=0.5 / n,
                    path_correlation_depth=FULL_CORRELATION,
                    use_stratified_sampling_for_each_interval=True,
                    antithetic_mapping="replay")
    return dict(time_sampling_method="stratified", path_correlation_depth=0,
                use_stratified_sampling_for_each_interval=True,
                antithetic_mapping="replay")


def _sobol_directions(m_initial, taps):
    """The 32 direction numbers of one Sobol dimension: initial m_1..m_s and the
    recurrence m_k = XOR over taps j of 2^j m_{k-j} (the primitive polynomial's terms,
    including x^s), as 32-bit integers with the most significant bit first."""
    m = list(m_initial)
    s = len(m)
    for k in range(s, 32):
        value = m[k - s]
        for j in taps:
            value ^= m[k - j] << j
        m.append(value)
    return tuple(m[k] << (31 - k) for k in range(32))


#: Sobol's 2nd dimension (polynomial x + 1), 3rd (x^2 + x + 1, m = 1, 3), 4th (x^3 + x +
#: 1, m = 1, 3, 1) and 5th (x^3 + x^2 + 1, m = 1, 1, 1): Joe and Kuo's initial numbers
#: (each a (0,1)-sequence; the pairs (0,1) t = 0, (3,4) t = 1: tests/test_sampling.py)
_SOBOL_DIRECTIONS = {1: _sobol_directions([1], [1]), 2: _sobol_directions([1, 3], [1, 2]),
                     3: _sobol_directions([1, 3, 1], [2, 3]),
                     4: _sobol_directions([1, 1, 1], [1, 3])}


def sobol_component(mi, index, dim: int, shift):
    """Component ``dim`` (0 to 4) of point ``index`` of Sobol's sequence, digitally
    shifted by ``shift``, as a 32-bit integer. Every component alone is a (0,1)-sequence
    (aligned runs of 2^k points stratify [0,1) in 2^k intervals), the first two form
    a (0,2)-sequence and the three a (1,3)-sequence."""
    import drjit as dr

    if dim == 0:
        return dr.brev(index) ^ shift
    y = mi.UInt32(0)
    for bit, v in enumerate(_SOBOL_DIRECTIONS[dim]):
        y ^= dr.select(((index >> bit) & 1) != 0, mi.UInt32(v), 0)
    return y ^ shift


def _reverse_permute(mi, x, seed):
    """A nested uniform (Owen) scramble of 32-bit values: a hash permutation in which
    each bit depends only on the bits above it (Laine-Karras style, applied to the
    bit-reversed value), so that every aligned run of a (t,s)-sequence stays one."""
    import drjit as dr

    x = dr.brev(x) + seed
    x ^= x * 0x6C50B47C
    x ^= x * 0xB82F1E52
    x ^= x * 0xC7AFE638
    x ^= x * 0x8D22F6E6
    return dr.brev(x)


def owen_sobol(mi, index, dim: int, seed):
    """Component ``dim`` of Sobol point ``index``, Owen-scrambled with ``seed``, as a
    32-bit integer."""
    return _reverse_permute(mi, sobol_component(mi, index, dim, 0), seed)


def _unit(mi, bits):
    return mi.Float(bits >> 8) * (1.0 / (1 << 24))  # 24 bits: exact and below 1


#: the generator g of the first hit's BSDF samples' rank-1 lattice sequence (lattice_2d):
#: an odd 32-bit integer whose every lattice of 2^m points, m = 3 to 27, has its closest
#: two points at least 0.71 of the hexagonal packing's distance apart (chosen by a search
#: over g mod 2^17, then bit by bit; tests/test_sampling.py measures it)
LATTICE_GENERATOR = 0x2B204613


def lattice_2d(mi, index, shift_x, shift_y):
    """Point ``index`` of a rank-1 lattice sequence in base 2, shifted on the torus by
    (``shift_x``, ``shift_y``) (Cranley-Patterson: every point uniform on [0,1)^2):
    phi(index) (1, g) mod 1, phi the radical inverse. Aligned runs of 2^m points are the
    lattice {(k, k g) / 2^m}: one point in every 1-D stratum of width 2^-m on either
    axis, and the points far apart on the torus, like a jittered grid whose rows are
    sheared (more even than a scrambled (0,2)-net's 2-D strata: 3% less variance on
    the walls of a Cornell box, docs/benchmarks.md)."""
    import drjit as dr

    x = dr.brev(index)
    return mi.Point2f(_unit(mi, x + shift_x), _unit(mi, x * LATTICE_GENERATOR + shift_y))


def decision_2d(mi, index, which: int, seed_x, seed_y):
    """A 2-D decision of a pixel's (or tile's) low-discrepancy sets at its shuffled
    ``index``: ``which`` 0, a light sample, is Sobol's (0,2)-sequence Owen-scrambled
    with the two seeds; 1, a BSDF sample, the lattice sequence shifted by them
    (:func:`lattice_2d`)."""
    if which == 1:
        return lattice_2d(mi, index, seed_x, seed_y)
    return mi.Point2f(_unit(mi, owen_sobol(mi, index, 0, seed_x)),
                      _unit(mi, owen_sobol(mi, index, 1, seed_y)))


def sobol_2d(mi, index, shift_x, shift_y):
    """Point ``index`` of the (0,2)-sequence in base 2 (Sobol's first two dimensions)
    with a random digital shift: every point is uniform on [0,1)^2, and aligned runs of
    2^k points stratify the square in every elementary interval of area 2^-k."""
    return mi.Point2f(_unit(mi, sobol_component(mi, index, 0, shift_x)),
                      _unit(mi, sobol_component(mi, index, 1, shift_y)))


#: how a pixel's low-discrepancy sets relate to its neighbours' (``pixel_sets``):
#: ``joint``, strata of one scrambled sequence per tile of pixels (:class:`JointSets`),
#: or ``independent``, each pixel's sets scrambled on their own
PIXEL_SETS = ("joint", "independent")

#: a tile of joint sets is 2^TILE_LEVELS pixels square (fewer when spp is so large
#: that the tile's sequence would not fit 32-bit indices)
TILE_LEVELS = 3


def _power_of_two_at_least(n: int) -> int:
    return 1 << max(0, int(n) - 1).bit_length()


def _morton(mi, x, y, levels: int):
    """The Morton (Z-order) code of the low ``levels`` bits of x and y."""
    code = mi.UInt32(0)
    for bit in range(levels):
        code |= ((x >> bit) & 1) << (2 * bit)
        code |= ((y >> bit) & 1) << (2 * bit + 1)
    return code


class JointSets:
    """Where a sample's low-discrepancy numbers come from when neighbouring pixels'
    sets are stratified together: one Owen-scrambled sequence per tile of 2^L x 2^L
    pixels, in which pixel p's sequence index s is point morton(p) * P + s (P: a power
    of two covering the pixel's indices). Aligned runs of the sequence are nets, so a
    pixel's set is one (its block of P), and so is the union of every 2x2, 4x4, ...
    block of pixels in Z order: the film positions, times and first-hit decisions of
    neighbouring pixels, whose splats a pixel averages, are stratified jointly.

    Indices beyond a pixel's P (adaptive counts above spp) start a fresh sequence, an
    *epoch*, scrambled on its own. With ``pilot_samples`` (adaptive sampling), the pilot
    samples come from each pixel's own sets (a tile of one pixel, its own scramble)
    and the rest from the joint sequence, scrambled apart from every pilot: a pixel's
    samples then never depend on its neighbours' pilots, which set its count (the
    estimate stays exactly unbiased; allocation.py).

    ``width``: the crop window's width (pixels are numbered row-major in it);
    ``spp``, ``group_size`` K, ``path_group_size`` Kp: the render's.
    """

    def __init__(self, width: int, spp: int, group_size: int, path_group_size: int,
                 pilot_samples: int = 0, height: int | None = None):
        self.width, self.pilot = int(width), int(pilot_samples)
        self._film_net(self.width, int(height or width))
        self.K = int(group_size)
        after = spp - self.pilot  # samples per pixel after the pilot (at spp)
        #: per kind of index: (first group, groups in a block, block size) of the pilot
        #: and of the rest (the pilot's None without adaptive sampling)
        self.parts = {}
        for kind, per in (("group", self.K), ("path", int(path_group_size)),
                          ("sample", self.K)):
            parts = [self._part(kind, 0, self.pilot, per) if self.pilot else None,
                     self._part(kind, self.pilot, after, per)]
            self.parts[kind] = parts
        largest = max(part[2] for parts in self.parts.values() for part in parts if part)
        self.levels = max(0, min(TILE_LEVELS, (33 - largest.bit_length()) // 2))

    def _film_net(self, width: int, height: int):
        """The image-wide net of film positions: one (0,2)-sequence over a square of
        2^a x 2^a pixels (2^a >= width, height), in which every pixel is an elementary
        interval holding 2^(32 - 2a) points per epoch. Point k's x digits are k's low
        bits reversed, so the pixel's column fixes k's low a bits; its row, Sobol's
        second dimension, is linear in k over GF(2): the next a bits z solve
        B z = row + (the rest's contribution), B the a x a block of the generator
        (invertible: the sequence's first 4^a points are one per pixel)."""
        a = max(width - 1, height - 1, 0).bit_length()
        #: levels a of the image's net, or None (an image too large: tiles' sets)
        self.image_levels = a if 2 * a <= 30 else None
        self.film_bits = 32 - 2 * a  #: bits of a pixel's index in the net, per epoch
        columns = [_SOBOL_DIRECTIONS[1][a + j] >> (32 - a) for j in range(a)] if a else []
        self._inverse = _gf2_inverse_columns(columns, a) if self.image_levels else []

    def film_point(self, mi, s, x, y):
        """Index in the image's net of point ``s`` of pixel (x, y) (s < 2^film_bits)."""
        import drjit as dr

        a = self.image_levels
        if not a:
            return s
        base = (dr.brev(x) >> (32 - a)) | (s << (2 * a))  # the column's digits, then s
        t = y ^ (sobol_component(mi, base, 1, 0) >> (32 - a))  # the row still to reach
        z = mi.UInt32(0)
        for r, column in enumerate(self._inverse):
            z ^= dr.select(((t >> r) & 1) != 0, mi.UInt32(column), 0)
        return base | (z << a)

    def _part(self, kind: str, first_sample: int, samples: int, per: int):
        """(first group of the part, groups per block, points per block): the groups
        (time or path groups) of a pixel's part, or for ``sample`` index-major blocks of
        K runs of that many time groups."""
        groups = _power_of_two_at_least(max(samples // per, 1))
        size = _power_of_two_at_least(self.K * groups) if kind == "sample" else groups
        return first_sample // per, groups, size

    def lane_keys(self, mi, pixel, seed_low, seed_high, pixel_key):
        """Per lane: (morton code in its tile, the tile's key, the pilot's key)."""
        x, y = pixel % self.width, pixel // self.width
        L = self.levels
        tiles_across = -(-self.width // (1 << L))
        tile = (y >> L) * tiles_across + (x >> L)
        tile_key = _pixel_key(mi, tile | 0x80000000, seed_low, seed_high)
        image_key = _pixel_key(mi, mi.UInt32(0xFFFFFFFF), seed_low, seed_high)
        return (_morton(mi, x, y, L), tile_key, _mix32(pixel_key ^ 0x5BD1E995), image_key,
                x, y)

    def locate(self, mi, keys, kind: str, group, index_in_group, path_group):
        """A lane's point in its sequence and that sequence's scramble key, for the
        pixel's sequence index of ``kind``: "group" (the time group), "path" (the path
        group) or "sample" (index-major: i * G' + g over the part's groups, so that the
        leading digits follow the group, not the index in it)."""
        import drjit as dr

        morton, tile_key, pilot_key, image_key, x, y = keys
        located = []
        for part, key, spread in zip(self.parts[kind], (pilot_key, tile_key), (0, 1)):
            if part is None:
                continue
            first, groups, size = part
            h = (path_group if kind == "path" else group) - first
            s = h & (groups - 1)
            if kind == "sample":
                s = index_in_group * groups + s
            epoch = h // groups  # beyond the block: a fresh sequence
            point = morton * size + s if spread else s
            film = self._film_located(mi, s, epoch, key if not spread else image_key, x, y,
                                      spread)
            located.append((point, _mix32(key ^ epoch * 0x9E3779B9)) + film)
        if len(located) == 1:
            return located[0]
        in_pilot = group < self.pilot // self.K
        return tuple(dr.select(in_pilot, a, b) for a, b in zip(*located))

    def _film_located(self, mi, s, epoch, key, x, y, spread: int):
        """(index, key) of the lane's film position and time: in the image's net (the
        part after any pilot), else, and in the pilot, in the pixel's own sequence."""
        if not spread or self.image_levels is None:
            return s, _mix32(key ^ (epoch * 0x9E3779B9 + 0x2545F491))
        if self.film_bits < 32:  # the pixel's indices beyond the net: more epochs
            epoch = (epoch << (32 - self.film_bits)) | (s >> self.film_bits)
            s = s & ((1 << self.film_bits) - 1)
        return self.film_point(mi, s, x, y), _mix32(key ^ epoch * 0x9E3779B9)


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
        self.base = _pixel_key(mi, pixel, seed, seed_high)
        base = self.base
        #: the tile's sequence for film, time and first hit (None: the pixel's own sets)
        self.joint = joint
        self.joint_keys = (None if joint is None
                           else joint.lane_keys(mi, pixel, seed, seed_high, base))
        self.key_group, _ = mi.sample_tea_32(base, group * 2, _KEY_ROUNDS)
        self.path_group = group if path_group is None else path_group
        self.key_path = (self.key_group if path_group is None
                         else mi.sample_tea_32(base, path_group * 2, _KEY_ROUNDS)[0])
        self.key_own, _ = mi.sample_tea_32(base, sample * 2 + 1, _KEY_ROUNDS)
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
        return _tagged(self.base, tag)

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
            scrambled = (value & keep) | (_reverse_permute(mi, value, _tagged(key, 1 + d))
                                         & ~keep)
            position.append(_unit(mi, scrambled << shift))
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
        seed_index, seed_x, seed_y = (_mix32(key ^ _hop_tag(mi, hop, k)) for k in range(3))
        return decision_2d(mi, _reverse_permute(mi, point, seed_index), which, seed_x, seed_y)

    def _joint_first_light(self):
        """The first hit's light sample with joint sets: Sobol's dimensions 3 and 4 at
        the film position's index in the image's net, so that film position and light
        sample form one 4-D set over the image: a splat weighs a pixel's samples by
        their film positions, and samples of similar weight then still stratify the
        light (3.3x less variance with a tent on direct light, docs/benchmarks.md)."""
        mi = self.mi
        film_index, film_key = self._lane_point(1)[2:]
        return mi.Point2f(*(_unit(mi, owen_sobol(mi, film_index, d, _tagged(film_key, 5 + d)))
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
            index, seed = index[2], _tagged(index[3], 3)
        # Owen scrambling, not a digital shift: a shift keeps the points' fine digits in
        # a fixed pattern, which aliases with a full waveform's 10^4-10^5 periods
        bits = owen_sobol(mi, index, 2, seed)
        if not double:
            return _unit(mi, bits)
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
        return decision_2d(mi, _reverse_permute(mi, index, seed_index), dim, seed_x, seed_y)

    def get_2d(self, stage, dim):
        key = self.key(stage)
        dim = self.mi.UInt32(dim)
        return self.mi.Point2f(hashed_uniform(self.mi, key, dim),
                               hashed_uniform(self.mi, key, dim + 1))


def index_major(mi, index_in_group, groups_per_pixel: int, group):
    """A sample's index-major index in its pixel's sequence, i * G + g, with the
    render's G (groups per pixel, from its spp) an opaque value: one kernel serves every
    spp (issue 40)."""
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
    "lattice_2d",
    "LATTICE_GENERATOR",
]
