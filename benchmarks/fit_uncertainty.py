"""Are the fit's reported standard deviations right? (issue 42, 2026-12-04)

Issue 42's target: every fitted component within 3 of its reported standard deviations.
Per scene, light and capture seed: `dopplertof capture` (the CLI, in this process), then
`dopplertof fit`'s fit; per body and fitted component the fitted value, the truth (the
capture scene's motion), and side by side the reported standard deviation and the
z-score (error / sd) of the old covariance (s^2 (J^T J)^+, fit_covariance.covariance's "plain" kind)
and of the new sandwich (fit_noise), both from the same final state of the same fit.
Ends with, per scene and light, the fraction of components within 3 sd, old and new,
the z-scores' RMS and the Birge ratios.

    cd benchmarks && PYTHONPATH=../src ../.venv/bin/python fit_uncertainty.py \\
        --scene translating_sphere user_meshes --light direct multipath --seeds 1 2 3 4

(a scene is a file of examples/; `direct` captures and fits with -D max_depth=2,
`multipath` as the scene is written; --spp: of the capture and the fit, 64 as
docs/differentiable.md's tables; --res: the capture's resolution, 48 as there; -D: more
-D values of the captures, e.g. -D spin=0; --json: every row. The rows also hold, for
comparison, z_plain: the sandwich without its outlying blocks' rule, and z_robust: the
cluster-robust sandwich from the residuals alone.)
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import json
import os
import sys
import tempfile
import time

import numpy as np

EXAMPLES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples")
LIGHTS = {"direct": ["-D", "max_depth=2"], "multipath": []}


def cli(args: list) -> tuple:
    """dopplertof.cli.main(args) in this process: its exit status and what it printed."""
    from dopplertof.cli import main

    text = io.StringIO()
    with contextlib.redirect_stdout(text), contextlib.redirect_stderr(text):
        rc = main(args)
    return rc, text.getvalue()


def capture(scene: str, light: str, seed: int, res: int, spp: int, folder: str,
            defines=()) -> tuple:
    """`dopplertof capture` of examples/SCENE.xml at res x res (with ``defines``, each
    "name=value"): its folder (None where it failed) and what it printed."""
    cap = os.path.join(folder, f"{scene}_{light}_{seed}")
    args = ["capture", os.path.join(EXAMPLES, f"{scene}.xml"), "-o", cap, "--spp", str(spp),
            "--seed", str(seed), "--quiet", "-D", f"res={res}"] + LIGHTS[light]
    rc, text = cli(args + [x for d in defines for x in ("-D", d)])
    return (cap if rc == 0 else None), text


def covariances(result) -> dict:
    """The standard deviations of the fit ``result``'s parameters under each covariance
    model, all from its final state (``result.final``, fit_covariance.FinalState; one
    fit, not four): "new" the fit's sandwich, "old" s^2 (J^T J)^+ (the "plain" kind),
    "robust" the sandwich of the residuals' own noise, "plain" the sandwich without its
    outlying blocks' rule; and "report", the fit's noise diagnostics (fit.json's
    settings.noise: the Birge ratio, the scale)."""
    from dopplertof.diff.fit_covariance import covariance
    from dopplertof.diff.fit_noise import CaptureNoise

    final = result.final

    def sigma(noise=None, theta=final.theta, kind="sandwich"):
        return covariance(final.state, final.seen, theta, noise, None, kind)[1]

    return {"old": sigma(theta=None, kind="plain"), "new": sigma(final.noise),
            "robust": sigma(CaptureNoise(final.noise.kinds, "residuals")),
            "plain": sigma(dataclasses.replace(final.noise, outliers=False)),
            "report": result.settings["noise"]}


def run_one(scene: str, light: str, seed: int, spp: int, res: int, angular: bool,
            folder: str, defines=()) -> list:
    """Capture and fit once; one row per body and fitted component."""
    from dopplertof.diff.fit import fit

    cap, text = capture(scene, light, seed, res, spp, folder, defines)
    assert cap is not None, text
    started = time.perf_counter()
    result = fit(cap, spp=spp, angular=angular, progress=False)
    seconds = time.perf_counter() - started
    record = covariances(result)
    rows = []
    for k, body in enumerate(result.bodies):
        per = 6 if angular else 3
        for j, (kind, unit) in enumerate([("linear", "m_s")] + [("angular", "rad_s")] * angular):
            fitted = body[f"{kind}_velocity_{unit}"]
            truth = body[f"truth_{kind}_velocity_{unit}"]
            errors = _errors(body, kind, np.subtract(fitted, truth))
            for a in range(3):
                i = k * per + 3 * j + a
                error = errors[a]
                old, new = record["old"][i], record["new"][i]
                rows.append({"scene": scene, "light": light, "seed": seed, "body": body["name"],
                             "component": f"{kind[0]}{'xyz'[a]}", "fitted": fitted[a],
                             "truth": truth[a], "sd_old": old, "z_old": error / old,
                             "sd_new": new, "z_new": error / new,
                             "z_robust": error / record["robust"][i],
                             "z_plain": error / record["plain"][i],
                             "birge": record["report"].get("birge_ratio") or float("nan"),
                             "scale": record["report"].get("scale"), "seconds": seconds})
    return rows


def _errors(body: dict, kind: str, error):
    """A component's errors as fit.json counts them in standard deviations: an angular
    velocity's without its spin along the body's symmetry axes (fit.json's
    ``angular_velocity_error_sigmas_leave_out``: a spin the captures cannot see)."""
    axes = [np.asarray(a, np.float64) for a in body.get("symmetry_axes") or []]
    if kind == "angular" and "angular_velocity_error_sigmas_leave_out" in body:
        error = error - sum((error @ a) * a for a in axes)
    return error


def _print_rows(rows) -> None:
    for r in rows:
        if not np.isfinite(r["sd_new"]):
            print(f"{r['scene']:>18} {r['light']:>9} {r['seed']:>4} {r['body'][:10]:>10} "
                  f"{r['component']:>3} {r['fitted']:+9.4f} {r['truth']:+9.4f}   not seen / "
                  "unconstrained: no sd")
            continue
        print(f"{r['scene']:>18} {r['light']:>9} {r['seed']:>4} {r['body'][:10]:>10} "
              f"{r['component']:>3} {r['fitted']:+9.4f} {r['truth']:+9.4f} "
              f"{r['sd_old']:9.4f} {r['z_old']:+7.2f} {r['sd_new']:9.4f} {r['z_new']:+7.2f} "
              f"B {r['birge']:.3g}{' (scaled)' if r['scale'] != 1.0 else ''}", flush=True)


def summarize(rows) -> list:
    """Per scene and light: components with an sd, within 3 sd old and new, z RMS."""
    out = []
    for key in sorted({(r["scene"], r["light"]) for r in rows}):
        group = [r for r in rows if (r["scene"], r["light"]) == key and np.isfinite(r["sd_new"])]
        if not group:
            continue
        z_old = np.array([r["z_old"] for r in group])
        z_new = np.array([r["z_new"] for r in group])
        birge = sorted({round(r["birge"], 3) for r in group})
        out.append({"scene": key[0], "light": key[1], "components": len(group),
                    "within_3_old": float(np.mean(np.abs(z_old) <= 3)),
                    "within_3_new": float(np.mean(np.abs(z_new) <= 3)),
                    "z_rms_old": float(np.sqrt(np.mean(z_old ** 2))),
                    "z_rms_new": float(np.sqrt(np.mean(z_new ** 2))),
                    "worst_old": float(z_old[np.argmax(np.abs(z_old))]),
                    "worst_new": float(z_new[np.argmax(np.abs(z_new))]),
                    "birge": birge})
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", nargs="+", default=["translating_sphere", "user_meshes"])
    p.add_argument("--light", nargs="+", default=["direct", "multipath"], choices=list(LIGHTS))
    p.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3, 4])
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--res", type=int, default=48)
    p.add_argument("--angular", action="store_true")
    p.add_argument("-D", dest="defines", action="append", default=[], metavar="NAME=VALUE",
                   help="a -D value of the captures (e.g. spin=0)")
    p.add_argument("--json", help="write every row and the summary here")
    a = p.parse_args(argv)
    import dopplertof

    dopplertof.set_variant("llvm_ad_rgb")
    rows = []
    print(f"{'scene':>18} {'light':>9} {'seed':>4} {'body':>10} {'c':>3} {'fitted':>9} "
          f"{'truth':>9} {'sd old':>9} {'z old':>7} {'sd new':>9} {'z new':>7}")
    with tempfile.TemporaryDirectory() as folder:
        for scene in a.scene:
            for light in a.light:
                for seed in a.seeds:
                    new = run_one(scene, light, seed, a.spp, a.res, a.angular, folder,
                                  a.defines)
                    _print_rows(new)
                    rows += new
    summary = summarize(rows)
    print("\nper scene and light: components within 3 sd, old (s^2 (J^T J)^+) -> new (sandwich)")
    for s in summary:
        print(f"{s['scene']:>18} {s['light']:>9}: {s['components']} components, within 3 sd "
              f"{s['within_3_old']:.0%} -> {s['within_3_new']:.0%}, z RMS {s['z_rms_old']:.2f} "
              f"-> {s['z_rms_new']:.2f}, worst {s['worst_old']:+.1f} -> {s['worst_new']:+.1f}, "
              f"Birge {s['birge']}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"rows": rows, "summary": summary, "argv": sys.argv[1:]}, f, indent=1,
                      default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
