"""Issue 42's fit target measured on every starter scene (issue 42, 2026-12-04)

Issue 42's target: the radial velocity within 2% for every body of the starter scenes,
spinning ones included, and every fitted component within 3 of its reported standard
deviations. Per starter scene (the XML files of examples/), light and capture seed:
`dopplertof capture SCENE -o ... -D res=N --spp S` then `dopplertof fit ... --spp S`
through dopplertof.cli.main in this process, and again with --angular where the linear
fit reports an unfitted rotation (fit.json's `unfitted_rotation` chi-square above its
threshold: the fit's warning). From fit.json, per body: the fitted radial velocity and its
standard deviation, the truth (fit.json's `capture_velocity_gt_median_m_s`, the capture's
own), the error in m/s and in %, and each fitted component's error in reported standard
deviations (fit.json's `*_velocity_error_sigmas`: the spin along a body's symmetry axes
left out; "-" for a component without an uncertainty). The last line counts the bodies
within 2% and the components within 3 sd.

    .venv/bin/python benchmarks/fit_scenes.py --light direct multipath --seeds 1

(`direct`: -D max_depth=2; `multipath`: the scene as written, skipped for a scene written
with max_depth 2, which is direct light already. --scenes: names of examples/ without
.xml, default every XML there; --res 48 or 48x48 (square: the scenes' `res`); --spp of the
capture and the fit, 64; --json: every row.)
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fit_uncertainty import EXAMPLES, LIGHTS, capture, cli  # noqa: E402  (the same scenes, lights, runs)

RADIAL_TARGET = 0.02   # issue 42: the radial velocity within 2%
SIGMA_TARGET = 3.0     # and every fitted component within 3 reported sd
NEAR_ZERO = 0.1        # m/s: a truth below this makes a relative error meaningless
UNITS = (("linear", "m_s"), ("angular", "rad_s"))


def starter_scenes() -> list:
    return sorted(f[:-4] for f in os.listdir(EXAMPLES) if f.endswith(".xml"))


def declared_defaults(scene: str) -> dict:
    """The scene's <default name=... value=...> values."""
    with open(os.path.join(EXAMPLES, f"{scene}.xml"), encoding="utf-8") as f:
        return dict(re.findall(r'<default\s+name="([^"]+)"\s+value="([^"]*)"', f.read()))


def fit(cap: str, spp: int, angular: bool, iterations=None) -> tuple:
    """fit.json of `dopplertof fit CAP`, or None and what the fit printed."""
    out = cap + ("_fit_angular" if angular else "_fit")
    args = ["fit", cap, "-o", out, "--spp", str(spp), "--quiet"] + ["--angular"] * angular
    args += ["--iterations", str(iterations)] if iterations else []
    started = time.perf_counter()
    rc, text = cli(args)
    if rc != 0:
        return None, text
    with open(os.path.join(out, "fit.json"), encoding="utf-8") as f:
        saved = json.load(f)
    saved["seconds"] = time.perf_counter() - started
    return saved, text


def unfitted_rotation(saved: dict) -> bool:
    """Whether the linear fit warns of an unfitted rotation (its chi-square test)."""
    return any((b.get("unfitted_rotation") or {}).get("chi_square", 0.0)
               > (b.get("unfitted_rotation") or {}).get("threshold", float("inf"))
               for b in saved["bodies"])


def rows_from_fit(saved: dict, scene: str, light: str, seed: int, kind: str) -> list:
    """One row per body of a fit.json: the radial velocity against the capture's truth
    and the fitted components' errors in reported standard deviations."""
    rows = []
    for b in saved["bodies"]:
        fitted, truth = b["radial_velocity_m_s"], b["capture_velocity_gt_median_m_s"]
        sigmas = list(b["linear_velocity_error_sigmas"])
        names = ["vx", "vy", "vz"]
        if kind == "angular":
            sigmas += list(b["angular_velocity_error_sigmas"])
            names += ["wx", "wy", "wz"]
        rows.append({"scene": scene, "light": light, "seed": seed, "fit": kind,
                     "body": b["name"], "pixels": b.get("interior_pixels"),
                     "radial": fitted, "radial_sd": b.get("radial_velocity_uncertainty_m_s"),
                     "truth": truth, "error_m_s": fitted - truth,
                     "error_pct": 100.0 * (fitted - truth) / abs(truth) if truth else None,
                     "radial_z": (fitted - truth) / sd if (sd := b.get(
                         "radial_velocity_uncertainty_m_s")) else None,
                     "components": dict(zip(names, sigmas)),
                     "velocity": {k: b.get(f"{k}_velocity_{u}") for k, u in UNITS},
                     "velocity_sd": {k: b.get(f"{k}_velocity_uncertainty_{u}") for k, u in UNITS},
                     "velocity_truth": {k: b.get(f"truth_{k}_velocity_{u}") for k, u in UNITS},
                     "iterations": saved.get("iterations"), "seconds": saved.get("seconds"),
                     "warnings": len(saved.get("warnings") or [])})
    return rows


def measure(scene: str, light: str, seed: int, res: int, spp: int, folder: str,
            iterations=None) -> list:
    """Capture and fit one scene; the rows, or one row that says why there are none."""
    base = {"scene": scene, "light": light, "seed": seed}
    if light == "multipath" and declared_defaults(scene).get("max_depth") == "2":
        return [dict(base, note="written with max_depth 2: direct light only")]
    cap, text = capture(scene, light, seed, res, spp, folder)
    if cap is None:
        return [dict(base, note="capture failed: " + _last(text))]
    saved, text = fit(cap, spp, False, iterations)
    if saved is None:
        return [dict(base, note="fit refused: " + _last(text))]
    rows = rows_from_fit(saved, scene, light, seed, "linear")
    if unfitted_rotation(saved):
        angular, text = fit(cap, spp, True, iterations)
        rows += (rows_from_fit(angular, scene, light, seed, "angular") if angular else
                 [dict(base, fit="angular", note="fit refused: " + _last(text))])
    return rows


def _last(text: str) -> str:
    lines = text.strip().splitlines()
    return lines[-1] if lines else "(nothing printed)"


def _sd(z) -> str:
    return "-" if z is None else f"{z:+.1f}"


def format_row(r: dict) -> str:
    head = f"| {r['scene']} | {r['light']} | {r['seed']} | "
    if "note" in r:
        return head + f"{r.get('fit', '')} | | {r['note']} | | | | |"
    pct = "" if r["error_pct"] is None else f"{r['error_pct']:+.2f}%"
    flag = "" if r["error_pct"] is None or abs(r["error_pct"]) <= 100 * RADIAL_TARGET else " **"
    sd = "" if r["radial_sd"] is None else f" +- {r['radial_sd']:.3f}"
    comps = ", ".join(f"{k} {_sd(z)}" for k, z in r["components"].items())
    return (head + f"{r['fit']} | {r['body']} ({r['pixels']} px) | {r['radial']:+.3f}{sd} | "
            f"{r['truth']:+.3f} | {r['error_m_s']:+.3f} | {pct}{flag} | {comps} |")


TABLE_HEAD = ("| scene | light | seed | fit | body (interior pixels) | radial m/s (fitted +- sd) | "
              "truth | error m/s | error % | components' errors in sd |\n"
              "|---|---|---|---|---|---|---|---|---|---|")


def summary_line(rows: list) -> str:
    bodies = [r for r in rows if "note" not in r]
    met = sum(abs(r["error_m_s"]) <= RADIAL_TARGET * abs(r["truth"]) for r in bodies)
    near = sum(abs(r["truth"]) < NEAR_ZERO for r in bodies)
    zs = [z for r in bodies for z in r["components"].values() if z is not None]
    unseen = sum(z is None for r in bodies for z in r["components"].values())
    within = sum(abs(z) <= SIGMA_TARGET for z in zs)
    return (f"{met} of {len(bodies)} fitted bodies within 2% of their radial truth "
            f"({near} with |truth| < {NEAR_ZERO} m/s, where a % means little); "
            f"{within} of {len(zs)} components with an sd within 3 sd ({unseen} without one)")


SUMMARY_HEAD = ("| scene | light | fit | body | seeds | radial truth m/s | radial error m/s, "
                "worst | error %, worst | within 2% | radial error in sd, worst | "
                "components within 3 sd (with an sd, of all) | worst z |\n"
                "|---|---|---|---|---|---|---|---|---|---|---|---|")


def summarize(rows: list) -> list:
    """Per scene, light, fit and body over the seeds: the radial velocity's worst error
    (m/s and %), how many seeds meet 2%, the components within 3 sd and the worst z."""
    out = []
    fitted = [r for r in rows if "note" not in r]
    for key in dict.fromkeys((r["scene"], r["light"], r["fit"], r["body"]) for r in fitted):
        group = [r for r in fitted if (r["scene"], r["light"], r["fit"], r["body"]) == key]
        errors = [r["error_m_s"] for r in group]
        worst = max(errors, key=abs)
        zs = [z for r in group for z in r["components"].values() if z is not None]
        count = sum(len(r["components"]) for r in group)
        truth = group[0]["truth"]
        radial_z = [r["radial_z"] for r in group if r["radial_z"] is not None]
        out.append({"scene": key[0], "light": key[1], "fit": key[2], "body": key[3],
                    "seeds": len(group), "truth": truth, "worst_m_s": worst,
                    "worst_pct": 100 * worst / abs(truth) if truth else None,
                    "within_2": sum(abs(e) <= RADIAL_TARGET * abs(truth) for e in errors),
                    "radial_z": max(radial_z, key=abs) if radial_z else None,
                    "within_3": sum(abs(z) <= SIGMA_TARGET for z in zs), "with_sd": len(zs),
                    "components": count, "worst_z": max(zs, key=abs) if zs else None})
    return out


def format_summary(s: dict) -> str:
    pct = "-" if s["worst_pct"] is None else f"{s['worst_pct']:+.2f}%"
    return (f"| {s['scene']} | {s['light']} | {s['fit']} | {s['body']} | {s['seeds']} | "
            f"{s['truth']:+.4g} | {s['worst_m_s']:+.3g} | {pct} | {s['within_2']} of "
            f"{s['seeds']} | {_sd(s['radial_z'])} | {s['within_3']} of {s['with_sd']} "
            f"({s['components']}) | {_sd(s['worst_z'])} |")


def _parse_res(text: str) -> int:
    w, _, h = text.lower().partition("x")
    if h and h != w:
        raise argparse.ArgumentTypeError("the starter scenes' res is square: NxN")
    return int(w)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scenes", nargs="+", default=None, help="default: every examples/*.xml")
    p.add_argument("--light", nargs="+", default=["direct", "multipath"], choices=list(LIGHTS))
    p.add_argument("--seeds", nargs="+", type=int, default=[1])
    p.add_argument("--res", type=_parse_res, default=48)
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--iterations", type=int, default=None, help="the fit's at most")
    p.add_argument("--json", help="write every row here")
    a = p.parse_args(argv)
    import dopplertof

    dopplertof.set_variant("llvm_ad_rgb")
    rows = []
    print(TABLE_HEAD, flush=True)
    with tempfile.TemporaryDirectory() as folder:
        for scene in a.scenes or starter_scenes():
            for light in a.light:
                for seed in a.seeds:
                    new = measure(scene, light, seed, a.res, a.spp, folder, a.iterations)
                    for r in new:
                        print(format_row(r), flush=True)
                    rows += new
    print("\nper scene, light, fit and body over the seeds (components: with an sd of all)")
    print(SUMMARY_HEAD)
    for s in summarize(rows):
        print(format_summary(s))
    print("\n" + summary_line(rows))
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump({"rows": rows, "argv": sys.argv[1:]}, f, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
