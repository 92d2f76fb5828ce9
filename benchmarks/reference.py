"""A reference of the published scene below the published reference's noise floor.

Renders ``cornell_box_moving.xml`` (the published fixtures) at ``--spp`` samples per
pixel in total (default 2^17, eight times the published 16384-spp reference) as
independent pieces of ``--piece-spp`` (seeds SEED_BASE + i), with the scene's ``auto``
sampling. Every piece is written to ``--out`` as it finishes (``piece_NNNN.npy``, atomic):
the pieces are the checkpoints, so that an interrupted run resumes where it stopped
(finished pieces are read back, the piece in progress is rendered again); the result is
bitwise the same however often it was interrupted. At the end it writes
``reference.npy`` (the pieces' mean, float64) and ``reference.json`` (settings, SHA-256
of the image's bytes, its own noise and the RMSE against the published reference).

The check: the RMSE against the published 16384-spp reference must be within
``--tolerance`` of the noise both carry, sqrt(published^2 + ours^2) (the published
one's given by ``--published-noise``, about 1.2e-5, ours estimated from the spread of
the pieces); exit status 1 when it is not. At another resolution (``--res``, for tests)
there is nothing to compare with: the check is skipped and said so.

    .venv/bin/python benchmarks/reference.py --out /tmp/reference [--spp 131072]
        [--piece-spp 4096] [--res N] [--max-pieces N]

Keep the image out of the repository: it is made by this script; its hash is in
docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
FIXTURES = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "fixtures", "published"))
#: seeds of the pieces: SEED_BASE + piece number (apart from the benchmarks' small seeds)
SEED_BASE = 1 << 40
EXPOSURE = 0.0015  #: the published Mitsuba 0.6 .npy files hold 1 + T * value


def image_hash(image: np.ndarray) -> str:
    """SHA-256 of a float64 image's bytes (C order)."""
    return hashlib.sha256(np.ascontiguousarray(image, dtype=np.float64).tobytes()).hexdigest()


def render_pieces(scene, out: str, spp: int, piece_spp: int, max_pieces: int | None):
    """The pieces' images (float64), each read back when it is on disk already, else
    rendered (resuming from its checkpoint) and written; None when ``max_pieces`` new
    pieces were rendered before the last."""
    import dopplertof
    from dopplertof.file_formats import write_npy

    pieces, rendered = [], 0
    for i in range(spp // piece_spp):
        path = os.path.join(out, f"piece_{i:04d}.npy")
        if os.path.exists(path):
            pieces.append(np.load(path))
            continue
        if max_pieces is not None and rendered >= max_pieces:
            return None
        # (no render checkpoint inside a piece: it would be saved after every pass, 128
        # times 19 MB per piece here; a piece is about a minute on 2 idle cores)
        image = np.asarray(dopplertof.render(scene, spp=piece_spp, seed=SEED_BASE + i),
                           dtype=np.float64)
        write_npy(path, image)
        pieces.append(image)
        rendered += 1
        print(f"piece {i + 1}/{spp // piece_spp} written", flush=True)
    return pieces


def compare_with_published(reference, own_noise, fixtures, published_noise, tolerance):
    """(RMSE against the published reference, the noise both carry, passed)."""
    published = (np.load(os.path.join(fixtures, "m06", "reference_spp_16384.npy"))
                 - 1.0) / EXPOSURE
    rmse = float(np.sqrt(np.mean((reference - published) ** 2)))
    noise = float(np.hypot(published_noise, own_noise))
    return rmse, noise, rmse <= tolerance * noise


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", required=True, help="folder for the pieces and the reference")
    p.add_argument("--spp", type=int, default=1 << 17)
    p.add_argument("--piece-spp", type=int, default=4096)
    p.add_argument("--res", type=int, help="another resolution (tests; no comparison)")
    p.add_argument("--max-pieces", type=int, help="stop after rendering this many pieces")
    p.add_argument("--fixtures", default=FIXTURES)
    p.add_argument("--published-noise", type=float, default=1.2e-5)
    p.add_argument("--tolerance", type=float, default=1.25)
    args = p.parse_args(argv)
    if args.piece_spp < 1 or args.spp % args.piece_spp or args.spp < 2 * args.piece_spp:
        print(f"error: --spp {args.spp} must be a multiple of --piece-spp "
              f"{args.piece_spp}, two pieces at least", file=sys.stderr)
        return 2
    xml = os.path.join(args.fixtures, "cornell_box_moving.xml")
    if not os.path.isfile(xml):
        print(f"error: the published scene is not at {xml} (--fixtures DIR)", file=sys.stderr)
        return 2

    import dopplertof
    from dopplertof.file_formats import write_json, write_npy
    from dopplertof.io import OutputError, make_output_folder

    try:
        out = make_output_folder(args.out)
    except OutputError as e:
        print(f"error: --out: {e}", file=sys.stderr)
        return 2
    dopplertof.set_variant("llvm_ad_rgb")
    overrides = {} if args.res is None else {"resx": args.res, "resy": args.res}
    scene = dopplertof.load_file(xml, overrides)
    pieces = render_pieces(scene, out, args.spp, args.piece_spp, args.max_pieces)
    if pieces is None:
        print(f"stopped after {args.max_pieces} new pieces: run again to resume")
        return 0
    stack = np.stack(pieces)
    reference = stack.mean(0)
    # its own noise: the pieces' spread per pixel, over their number
    own_noise = float(np.sqrt(np.mean(stack.var(0, ddof=1) / len(pieces))))
    summary = {"spp": args.spp, "piece_spp": args.piece_spp, "seeds": [SEED_BASE,
               SEED_BASE + len(pieces) - 1], "shape": list(reference.shape),
               "sha256": image_hash(reference), "own_noise_rmse": own_noise}
    status = 0
    if args.res is None:
        rmse, noise, passed = compare_with_published(
            reference, own_noise, args.fixtures, args.published_noise, args.tolerance)
        summary.update(rmse_against_published=rmse, expected_noise=noise, passed=passed)
        print(f"RMSE against the published reference {rmse:.3e} (the noise both carry "
              f"{noise:.3e}; ours {own_noise:.3e}): {'within' if passed else 'BEYOND'} "
              f"{args.tolerance}x")
        status = 0 if passed else 1
    else:
        print(f"--res {args.res}: no published reference at that size, not compared")
    write_npy(os.path.join(out, "reference.npy"), reference)
    write_json(os.path.join(out, "reference.json"), summary)
    print(f"reference sha256 {summary['sha256']}")
    print(json.dumps({k: summary[k] for k in ("spp", "own_noise_rmse")}))
    return status


if __name__ == "__main__":
    raise SystemExit(main())
