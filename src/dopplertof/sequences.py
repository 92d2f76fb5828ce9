"""Random numbers as functions of integers on Dr.Jit arrays: integer hashes (a stream
key and a dimension to a uniform number), and low-discrepancy sequences of 32-bit
integers: Sobol's first five
dimensions with digital shifts or Owen scrambling, and a rank-1 lattice sequence in
base 2 with a Cranley-Patterson shift (the points a pixel's film position, time and
first hit's decisions take: sampling.CorrelatedStreams)."""

from __future__ import annotations


def sobol_directions(m_initial, taps):
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
SOBOL_DIRECTIONS = {1: sobol_directions([1], [1]), 2: sobol_directions([1, 3], [1, 2]),
                     3: sobol_directions([1, 3, 1], [2, 3]),
                     4: sobol_directions([1, 1, 1], [1, 3])}


def sobol_component(mi, index, dim: int, shift):
    """Component ``dim`` (0 to 4) of point ``index`` of Sobol's sequence, digitally
    shifted by ``shift``, as a 32-bit integer. Every component alone is a (0,1)-sequence
    (aligned runs of 2^k points stratify [0,1) in 2^k intervals), the first two form
    a (0,2)-sequence and the three a (1,3)-sequence."""
    import drjit as dr

    if dim == 0:
        return dr.brev(index) ^ shift
    y = mi.UInt32(0)
    for bit, v in enumerate(SOBOL_DIRECTIONS[dim]):
        y ^= dr.select(((index >> bit) & 1) != 0, mi.UInt32(v), 0)
    return y ^ shift


def reverse_permute(mi, x, seed):
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
    return reverse_permute(mi, sobol_component(mi, index, dim, 0), seed)


def unit_float(mi, bits):
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
    return mi.Point2f(unit_float(mi, x + shift_x), unit_float(mi, x * LATTICE_GENERATOR + shift_y))


def decision_2d(mi, index, which: int, seed_x, seed_y):
    """A 2-D decision of a pixel's (or tile's) low-discrepancy sets at its shuffled
    ``index``: ``which`` 0, a light sample, is Sobol's (0,2)-sequence Owen-scrambled
    with the two seeds; 1, a BSDF sample, the lattice sequence shifted by them
    (:func:`lattice_2d`)."""
    if which == 1:
        return lattice_2d(mi, index, seed_x, seed_y)
    return mi.Point2f(unit_float(mi, owen_sobol(mi, index, 0, seed_x)),
                      unit_float(mi, owen_sobol(mi, index, 1, seed_y)))


def sobol_2d(mi, index, shift_x, shift_y):
    """Point ``index`` of the (0,2)-sequence in base 2 (Sobol's first two dimensions)
    with a random digital shift: every point is uniform on [0,1)^2, and aligned runs of
    2^k points stratify the square in every elementary interval of area 2^-k."""
    return mi.Point2f(unit_float(mi, sobol_component(mi, index, 0, shift_x)),
                      unit_float(mi, sobol_component(mi, index, 1, shift_y)))


# ---- Hashes ----

def mix32(x):
    """A 32-bit integer hash with full avalanche (multiply-xorshift, two rounds)."""
    x = x ^ (x >> 16)
    x = x * 0x7FEB352D
    x = x ^ (x >> 15)
    x = x * 0x846CA68B
    return x ^ (x >> 16)


def tagged(key, tag: int):
    """A scramble seed from a stream key and a tag (one cheap hash)."""
    return mix32(key ^ ((tag * 0x9E3779B9) & 0xFFFFFFFF))


def hashed_uniform(mi, key, dim):
    """Uniform number in [0, 1) for a stream key and a dimension: two hash rounds, the
    dimension spread first so that consecutive dimensions are unrelated."""
    x = mix32(key ^ mix32(dim * 0x9E3779B9 + 0x7F4A7C15))
    return mi.Float(x >> 8) * (1.0 / (1 << 24))  # 24 bits: exact and below 1


#: TEA rounds that derive a pixel's stream key (once per path)
KEY_ROUNDS = 8


def pixel_stream_key(mi, pixel, seed_low, seed_high):
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
    key, _ = mi.sample_tea_32(pixel, seed_low, KEY_ROUNDS)
    if seed_high is None:
        return key
    key, _ = mi.sample_tea_32(key, seed_high, KEY_ROUNDS)
    return key
