"""Equal time against the published Mitsuba 0.6 code, side by side in one sitting.

    .venv/bin/python benchmarks/race_published.py --peer SRC [--peer-spp 1024] [--spp 4096]
        [--fixtures DIR] [--seed 1]

``SRC`` is the published code built by ../shared/peer/build-m06.sh (its ``dist/mitsuba``
and ``config_example/``). The race, one process at a time: the published code's best
unbiased mode (antithetic time, path correlation) renders its own Cornell box config at
``--peer-spp``, then dopplertof renders the same scene with the recommended settings
(``-P time_sampling_method=auto -P adaptive_sampling=true``) at ``--spp``. Both are
measured against the 2^17-spp deep reference with its own noise removed
(sqrt(rmse^2 - 2.93e-6^2), the fixtures' README). Ours is then scaled to the published
code's wall time (variance inversely proportional to time): the equal-time ratio of the
two RMSEs is the last line. Machines differ by up to 3x from one day to the next, so only
a ratio measured side by side holds.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from published import EXPOSURE, FIXTURES  # noqa: E402  (the fixtures and the scene's T)

REFERENCE_NOISE = 2.93e-6  #: the deep reference's own RMSE (the fixtures' README)
#: the published code's config of this race, under its source tree
PEER_CONFIG = os.path.join("config_example", "cornell-box", "point_light", "max_depth_4",
                           "freq_1.000_offset_0.000_low_only")


def rmse_without_reference_noise(image, reference) -> float:
    squared = float(np.mean((np.asarray(image, np.float64) - reference) ** 2))
    return float(np.sqrt(max(squared - REFERENCE_NOISE ** 2, 0.0)))


def race_peer(src: str, spp: int, out: str):
    """The published code's render at ``spp`` (its time average) and its wall seconds."""
    config = os.path.join(src, PEER_CONFIG)
    binary = os.path.join(src, "dist", "mitsuba")
    env = dict(os.environ, LD_LIBRARY_PATH=os.path.join(src, "dist"))
    started = time.perf_counter()
    subprocess.run([binary, "-p", str(os.cpu_count() or 1), f"-Dsamples={spp // 2}",
                    "-Dres=256", "-Dmaxdepth=4", "-o", out,
                    "antithetic_path_corr_direction.xml"], cwd=config, env=env, check=True,
                   stdout=subprocess.DEVNULL)
    seconds = time.perf_counter() - started
    return (np.load(out) - 1.0) / EXPOSURE, seconds


def race_ours(fixtures: str, spp: int, seed: int):
    import dopplertof

    dopplertof.set_variant()
    scene = dopplertof.load_file(os.path.join(fixtures, "cornell_box_moving.xml"))
    params = dict(time_sampling_method="auto", adaptive_sampling=True)
    dopplertof.render(scene, spp=128, seed=0, params=params)  # (kernels compiled)
    started = time.perf_counter()
    image = dopplertof.render(scene, spp=spp, seed=seed, params=params)
    return np.asarray(image, np.float64), time.perf_counter() - started


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--peer", required=True, metavar="SRC",
                   help="the published code's built source tree (build-m06.sh's $SRC)")
    p.add_argument("--peer-spp", type=int, default=1024)
    p.add_argument("--spp", type=int, default=4096)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--fixtures", default=FIXTURES)
    args = p.parse_args(argv)
    for path, what in ((os.path.join(args.peer, "dist", "mitsuba"), "--peer"),
                       (os.path.join(args.peer, PEER_CONFIG), "--peer"),
                       (os.path.join(args.fixtures, "deep_reference_2e17.npy"), "--fixtures")):
        if not os.path.exists(path):
            print(f"error: {path} not found ({what})", file=sys.stderr)
            return 2
    reference = np.load(os.path.join(args.fixtures, "deep_reference_2e17.npy")).astype(
        np.float64)
    with tempfile.TemporaryDirectory() as scratch:
        peer_image, peer_seconds = race_peer(args.peer, args.peer_spp,
                                             os.path.join(scratch, "peer.npy"))
    ours_image, ours_seconds = race_ours(args.fixtures, args.spp, args.seed)
    peer_rmse = rmse_without_reference_noise(peer_image, reference)
    ours_rmse = rmse_without_reference_noise(ours_image, reference)
    ours_at_peer_time = ours_rmse * np.sqrt(ours_seconds / peer_seconds)
    print(f"published, antithetic + path correlation, {args.peer_spp} spp: "
          f"{peer_seconds:.1f} s, RMSE {peer_rmse:.3e}")
    print(f"dopplertof, auto + adaptive_sampling, {args.spp} spp: {ours_seconds:.1f} s, "
          f"RMSE {ours_rmse:.3e} ({ours_at_peer_time:.3e} scaled to {peer_seconds:.1f} s)")
    print(f"per sample: {peer_seconds / args.peer_spp / (ours_seconds / args.spp):.2f}x "
          "faster")
    print(f"equal-time RMSE ratio (published / ours): {peer_rmse / ours_at_peer_time:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
