"""The offline wheelhouse of issue 44 (tools/offline_wheels.sh, tools/repack_wheel.py).

The slow tests download the wheels (skipped, with the reason, where the package index cannot
be reached), check that the wheelhouse stays under 50 MB with Mitsuba repacked to
cuda_ad_rgb and llvm_ad_rgb, install the repack with ``pip install --no-index --target``
into a scratch folder and render with llvm_ad_rgb from it in a subprocess. The wheelhouse
is built for Python 3.12 where an interpreter of that version is found (the GPU image's),
else for the running one. The fast tests repack a small wheel made here."""

import base64
import glob
import hashlib
import os
import shutil
import subprocess
import sys
import zipfile

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(ROOT, "tools", "offline_wheels.sh")
REPACK = os.path.join(ROOT, "tools", "repack_wheel.py")
LIMIT = 50_000_000
VARIANTS = ["scalar_rgb", "llvm_ad_rgb", "llvm_ad_spectral", "cuda_ad_rgb", "cuda_ad_mono"]


def record_hash(data):
    return "sha256=" + base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(
        b"=").decode()


def check_record(wheel):
    """Every file of the wheel in RECORD once, with its hash and size, and nothing else."""
    with zipfile.ZipFile(wheel) as z:
        names = [n for n in z.namelist() if not n.endswith("/")]
        record_name = next(n for n in names if n.endswith(".dist-info/RECORD"))
        rows = [line.split(",") for line in z.read(record_name).decode().splitlines() if line]
        listed = {r[0]: r for r in rows}
        assert len(listed) == len(rows) and sorted(listed) == sorted(names)
        for name in names:
            if name != record_name:
                data = z.read(name)
                assert listed[name][1:] == [record_hash(data), str(len(data))], name
        assert listed[record_name][1:] == ["", ""]
        return names


# ---- A small wheel repacked here (no network) ----

def fake_mitsuba_wheel(folder):
    path = os.path.join(folder, "mitsuba-3.9.1-cp312-cp312-manylinux_2_28_x86_64.whl")
    files = {"mitsuba/__init__.py": b"from .config import MI_VARIANTS\n",
             "mitsuba/config.py": b'"""generated"""\nMI_VARIANTS = %r\n' % VARIANTS,
             "mitsuba/libmitsuba.so": b"shared code",
             "mitsuba/plugins/path.so": b"plugin",
             "mitsuba/data/srgb.coeff": b"spectral table",
             "mitsuba/data/ior/Au.eta.spd": b"ior",
             "mitsuba/include/mitsuba/mitsuba.h": b"header",
             "mitsuba/cmake/mitsuba/mitsubaConfig.cmake": b"cmake",
             "mitsuba-3.9.1.dist-info/METADATA":
                 b"Metadata-Version: 2.1\nName: mitsuba\nVersion: 3.9.1\n",
             "mitsuba-3.9.1.dist-info/WHEEL":
                 b"Wheel-Version: 1.0\nRoot-Is-Purelib: false\n"
                 b"Tag: cp312-cp312-manylinux_2_28_x86_64\n"}
    files.update({f"mitsuba/{v}.cpython-312-x86_64-linux-gnu.so": v.encode() for v in VARIANTS})
    with zipfile.ZipFile(path, "w") as z:
        for name, data in files.items():
            z.writestr(name, data)
        z.writestr("mitsuba-3.9.1.dist-info/RECORD", "".join(
            f"{n},{record_hash(d)},{len(d)}\n" for n, d in files.items())
            + "mitsuba-3.9.1.dist-info/RECORD,,\n")
    return path


def test_repack_keeps_the_variants_asked_for_and_a_consistent_record(tmp_path):
    wheel = fake_mitsuba_wheel(str(tmp_path))
    out = tmp_path / "out"
    out.mkdir()
    done = subprocess.run([sys.executable, REPACK, wheel, str(out)], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    repacked = done.stdout.strip()
    assert os.path.basename(repacked) == "mitsuba-3.9.1+rgb-cp312-cp312-manylinux_2_28_x86_64.whl"
    names = check_record(repacked)
    modules = sorted(n for n in names if n.endswith("-linux-gnu.so"))
    assert modules == [f"mitsuba/{v}.cpython-312-x86_64-linux-gnu.so"
                       for v in ("cuda_ad_rgb", "llvm_ad_rgb")]
    assert "mitsuba/data/srgb.coeff" not in names and "mitsuba/data/ior/Au.eta.spd" in names
    assert not [n for n in names if n.startswith(("mitsuba/include/", "mitsuba/cmake/"))]
    with zipfile.ZipFile(repacked) as z:
        config = z.read("mitsuba/config.py").decode()
        assert "MI_VARIANTS = ['cuda_ad_rgb', 'llvm_ad_rgb']" in config
        assert b"Version: 3.9.1+rgb\n" in z.read("mitsuba-3.9.1+rgb.dist-info/METADATA")
    # pip installs it offline as any wheel (the file content is not a real Mitsuba)
    target = tmp_path / "site"
    pip = subprocess.run([sys.executable, "-m", "pip", "install", "--no-index", "--no-deps",
                          "--disable-pip-version-check", "--target", str(target),
                          "--python-version", "3.12", "--only-binary=:all:",
                          "--platform", "manylinux_2_28_x86_64", repacked],
                         capture_output=True, text=True, timeout=120)
    assert pip.returncode == 0, pip.stdout + pip.stderr
    assert (target / "mitsuba" / "llvm_ad_rgb.cpython-312-x86_64-linux-gnu.so").exists()
    assert (target / "mitsuba-3.9.1+rgb.dist-info" / "RECORD").exists()


@pytest.mark.parametrize("variants, message", [
    ("llvm_ad_rgb,cuda_ad_spectral_polarized", "no variant cuda_ad_spectral_polarized inside"),
])
def test_repack_of_a_variant_the_wheel_lacks_is_one_line(tmp_path, variants, message):
    wheel = fake_mitsuba_wheel(str(tmp_path))
    done = subprocess.run([sys.executable, REPACK, wheel, str(tmp_path), "--variants",
                           variants], capture_output=True, text=True, timeout=60)
    assert done.returncode == 1 and message in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert not glob.glob(str(tmp_path / "*+rgb*"))


@pytest.mark.parametrize("args, message", [
    ((), "no OUT folder"),
    (("a", "b"), "one OUT folder only"),
    (("a", "--python-version", "twelve"), "--python-version twelve: expected 3.N"),
    (("a", "--fast"), "unknown argument '--fast'"),
])
def test_offline_wheels_bad_arguments_are_one_line(tmp_path, args, message):
    done = subprocess.run(["bash", SCRIPT, *args], capture_output=True, text=True, timeout=30,
                          cwd=tmp_path)
    assert done.returncode == 2 and message in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not os.listdir(tmp_path)


def test_offline_wheels_refuses_a_folder_with_files(tmp_path):
    (tmp_path / "old.whl").write_text("an earlier wheelhouse")
    done = subprocess.run(["bash", SCRIPT, str(tmp_path)], capture_output=True, text=True,
                          timeout=30)
    assert done.returncode == 2 and "is not an empty folder" in done.stderr
    assert os.listdir(tmp_path) == ["old.whl"]


# ---- The real wheelhouse (downloads: slow) ----

def python_for_wheelhouse():
    """(interpreter, 'X.Y'): a Python 3.12 with pip where one is found, else this one."""
    candidates = [sys.executable] if sys.version_info[:2] == (3, 12) else []
    candidates += [c for c in [shutil.which("python3.12")] if c]
    candidates += sorted(glob.glob(os.path.expanduser("~/.pyenv/versions/3.12*/bin/python3.12")))
    for candidate in candidates:
        try:
            ok = subprocess.run([candidate, "-m", "pip", "--version"], capture_output=True,
                                timeout=60).returncode == 0
        except (OSError, subprocess.TimeoutExpired):
            ok = False
        if ok:
            return candidate, "3.12"
    return sys.executable, f"{sys.version_info[0]}.{sys.version_info[1]}"


#: wheelhouses built in this run, by Python version
BUILT = {}


def build_wheelhouse(tmp_path_factory, version):
    """(folder, the script's stdout) for CPython ``version``, built once per test run;
    skipped where the package index cannot be reached."""
    if version in BUILT:
        return BUILT[version]
    probe_dir = tmp_path_factory.mktemp("probe")
    probe = subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps",
                            "--disable-pip-version-check", "--only-binary=:all:", "-d",
                            str(probe_dir), "iniconfig"], capture_output=True, text=True,
                           timeout=120)
    if probe.returncode != 0:
        last = (probe.stderr.strip().splitlines() or ["no output"])[-1]
        pytest.skip(f"the package index cannot be reached (pip download iniconfig: {last})")
    out = tmp_path_factory.mktemp("wheelhouse") / f"wheels{version}"
    done = subprocess.run(["bash", SCRIPT, str(out), "--python-version", version],
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHON": sys.executable})
    assert done.returncode == 0, done.stdout + done.stderr
    BUILT[version] = out, done.stdout
    return BUILT[version]


@pytest.fixture(scope="module")
def wheelhouse(tmp_path_factory):
    """(folder, script's stdout, interpreter): for Python 3.12 where one is found."""
    python, version = python_for_wheelhouse()
    return (*build_wheelhouse(tmp_path_factory, version), python)


@pytest.mark.slow
def test_wheelhouse_is_under_50_mb_with_mitsuba_repacked(wheelhouse):
    out, stdout, _ = wheelhouse
    wheels = sorted(os.listdir(out))
    total = sum(os.path.getsize(out / w) for w in wheels)
    assert total < LIMIT and f"{total / 1e6:.2f} MB  total, {len(wheels)} wheels" in stdout
    assert all(w.endswith(".whl") for w in wheels)
    for name in ("mitsuba-3.9.", "drjit-1.5.", "pytest-", "pluggy-", "iniconfig-", "tqdm-"):
        assert sum(w.startswith(name) for w in wheels) == 1, (name, wheels)
    mitsuba = next(w for w in wheels if w.startswith("mitsuba-"))
    assert "+rgb-" in mitsuba
    names = check_record(out / mitsuba)
    modules = sorted(n.split(".")[0] for n in names
                     if n.count("/") == 1 and n.endswith("-linux-gnu.so")
                     and n.split("/")[1].startswith(("scalar_", "llvm_", "cuda_")))
    assert modules == ["mitsuba/cuda_ad_rgb", "mitsuba/llvm_ad_rgb"]


RENDER = """
import os, sys
import drjit as dr
import mitsuba as mi
target = os.path.realpath(sys.argv[1])
assert os.path.realpath(mi.__file__).startswith(target + os.sep), mi.__file__
assert os.path.realpath(dr.__file__).startswith(target + os.sep), dr.__file__
mi.set_variant("llvm_ad_rgb")
image = mi.render(mi.load_dict(mi.cornell_box()), spp=4, seed=0)
print("shape", image.shape, "mean", dr.mean(image, axis=None))
"""


@pytest.mark.slow
def test_repacked_wheel_installs_offline_and_renders_with_llvm(wheelhouse, tmp_path):
    from dopplertof.backend import find_libllvm

    libllvm = find_libllvm()
    if libllvm is None:
        pytest.skip("no libLLVM >= 16 on this machine for llvm_ad_rgb")
    out, _, python = wheelhouse
    target = tmp_path / "site"
    pip = subprocess.run([python, "-m", "pip", "install", "--no-index", "--find-links", str(out),
                          "--disable-pip-version-check", "--target", str(target), "mitsuba"],
                         capture_output=True, text=True, timeout=300)
    assert pip.returncode == 0, pip.stdout + pip.stderr
    installed = sorted(p.name for p in target.iterdir())
    assert "mitsuba-3.9.1+rgb.dist-info" in installed and "drjit-1.5.0.dist-info" in installed
    assert not (target / "mitsuba" / "data" / "srgb.coeff").exists()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    done = subprocess.run([python, "-c", RENDER, str(target)], capture_output=True, text=True,
                          timeout=300, cwd=tmp_path,
                          env={**env, "PYTHONPATH": str(target), "DRJIT_LIBLLVM_PATH": libllvm})
    assert done.returncode == 0, done.stdout + done.stderr
    words = done.stdout.split()
    assert words[:4] == ["shape", "(256,", "256,", "3)"], done.stdout
    mean = float(words[-1].strip("[]"))
    assert 0.05 < mean < 0.5, done.stdout  # the Cornell box's mean, about 0.147


@pytest.mark.slow
def test_gpu_check_installs_from_the_wheelhouse_and_passes_on_llvm(tmp_path_factory, tmp_path):
    """tools/gpu_check.sh --wheelhouse, the dry run: the wheelhouse for this interpreter's
    Python, installed into a scratch folder that the steps import mitsuba from."""
    from dopplertof.backend import find_libllvm

    if find_libllvm() is None:
        pytest.skip("no libLLVM >= 16 on this machine for llvm_ad_rgb")
    out, _ = build_wheelhouse(tmp_path_factory, f"{sys.version_info[0]}.{sys.version_info[1]}")
    site = tmp_path / "site"
    done = subprocess.run(["bash", os.path.join(ROOT, "tools", "gpu_check.sh"), "--wheelhouse",
                           str(out), "--python", sys.executable, "--variant", "llvm_ad_rgb",
                           "--quick", "--out", "check"], capture_output=True, text=True,
                          timeout=400, cwd=tmp_path,
                          env={**os.environ, "GPU_CHECK_SITE": str(site)})
    assert done.returncode == 0, done.stdout + done.stderr
    text = (tmp_path / "check" / "report.txt").read_text()
    assert "software: mitsuba 3.9.1+rgb, drjit 1.5.0" in text and "install ok" in text
    assert text.rstrip().endswith("result: PASS")
    assert (site / "mitsuba-3.9.1+rgb.dist-info").is_dir()
    assert "Successfully installed drjit-1.5.0 mitsuba-3.9.1+rgb" in (
        tmp_path / "check" / "install.log").read_text()
