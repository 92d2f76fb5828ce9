"""Joint low-discrepancy sets of neighbouring pixels (``pixel_sets = "joint"``): one
Owen-scrambled sequence per tile of pixels in Z order, and the film positions one
(0,2)-net over the whole image (sampling.CorrelatedStreams draws from them)."""

from __future__ import annotations

from .sequences import SOBOL_DIRECTIONS, mix32, pixel_stream_key, sobol_component


def gf2_inverse_columns(columns, bits: int) -> list:
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
        columns = [SOBOL_DIRECTIONS[1][a + j] >> (32 - a) for j in range(a)] if a else []
        self._inverse = gf2_inverse_columns(columns, a) if self.image_levels else []

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
        tile_key = pixel_stream_key(mi, tile | 0x80000000, seed_low, seed_high)
        image_key = pixel_stream_key(mi, mi.UInt32(0xFFFFFFFF), seed_low, seed_high)
        return (_morton(mi, x, y, L), tile_key, mix32(pixel_key ^ 0x5BD1E995), image_key,
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
            located.append((point, mix32(key ^ epoch * 0x9E3779B9)) + film)
        if len(located) == 1:
            return located[0]
        in_pilot = group < self.pilot // self.K
        return tuple(dr.select(in_pilot, a, b) for a, b in zip(*located))

    def _film_located(self, mi, s, epoch, key, x, y, spread: int):
        """(index, key) of the lane's film position and time: in the image's net (the
        part after any pilot), else, and in the pilot, in the pixel's own sequence."""
        if not spread or self.image_levels is None:
            return s, mix32(key ^ (epoch * 0x9E3779B9 + 0x2545F491))
        if self.film_bits < 32:  # the pixel's indices beyond the net: more epochs
            epoch = (epoch << (32 - self.film_bits)) | (s >> self.film_bits)
            s = s & ((1 << self.film_bits) - 1)
        return self.film_point(mi, s, x, y), mix32(key ^ epoch * 0x9E3779B9)
