"""A fast start (issue 24, section 7): the command line's help and its usage errors
import nothing heavy, the kernel of a capture serves every capture after it, and a
second ``make demo`` renders nothing when its outputs are up to date. No test is
timed: each checks the cause of the time (what is imported, what is compiled, what
make would run); benchmarks/startup.py measures the times."""

import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SRC = os.path.join(ROOT, "src")
SPHERE = os.path.join(ROOT, "examples", "translating_sphere.xml")
#: what a usage error or --help has no use for
HEAVY = ("mitsuba", "drjit", "matplotlib", "dask", "scipy")
#: what --help has no use for either (a usage error may check values with it)
HELP_HEAVY = HEAVY + ("numpy", "h5py")
#: the packages whose names are imported on first use (dopplertof.lazy.lazy_exports)
LAZY_PACKAGES = ("dopplertof", "dopplertof.cameras", "dopplertof.dataset", "dopplertof.diff",
                 "dopplertof.experiments", "dopplertof.render", "dopplertof.fmcw")


def in_fresh_python(code: str):
    """``code`` run in a fresh interpreter, this tree's sources first on the path."""
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, cwd=ROOT, timeout=300)


def cli_in_fresh_python(*argv, heavy=HEAVY) -> tuple:
    """(exit code, stderr, the ``heavy`` modules imported) of ``dopplertof ARGV`` run
    in a fresh interpreter, this tree's sources first on the path."""
    code = (f"import sys\nfrom dopplertof.cli import main\n"
            f"try:\n    rc = main({list(argv)!r})\nexcept SystemExit as e:\n    rc = e.code\n"
            f"print('imported', *[m for m in {heavy!r} if m in sys.modules])\n"
            f"sys.exit(rc)")
    result = in_fresh_python(code)
    imported = [line.split()[1:] for line in result.stdout.splitlines()
                if line.startswith("imported")]
    return result.returncode, result.stderr, imported[-1] if imported else None


@pytest.mark.parametrize("argv", [["--help"], ["capture", "--help"], ["fit", "--help"],
                                  ["render"], ["sweep", "--help"], ["fmcw", "--help"]],
                         ids=lambda a: " ".join(a))
def test_help_and_argparse_errors_import_nothing_heavy(argv):
    """Not NumPy either: the package's names and the subcommands' modules are
    imported on first use (--help in 0.15 s here, 0.7 s with them all)."""
    code, err, imported = cli_in_fresh_python(*argv, heavy=HELP_HEAVY)
    assert code in (0, 2), err
    assert imported == [], imported


def test_import_dopplertof_imports_nothing_heavy():
    result = in_fresh_python(f"import sys, dopplertof\n"
                             f"print(*[m for m in {HELP_HEAVY!r} if m in sys.modules])")
    assert result.returncode == 0 and result.stdout.split() == [], result.stdout + result.stderr


def test_loading_capturing_and_writing_import_no_scipy_or_matplotlib(tmp_path):
    """A scene with a rotating body (rigid keyframes: quaternions) loads without SciPy
    (0.5 s of import), and its capture and its folder, previews included
    (dopplertof.previews), without Matplotlib (0.5 s, and 0.15 s a preview drawn)."""
    scene = os.path.join(ROOT, "examples", "rotating_cube.xml")
    out = str(tmp_path / "out")
    result = in_fresh_python(
        f"import sys, dopplertof\nscene = dopplertof.load_file({scene!r}, res=8)\n"
        f"dopplertof.capture(scene, spp=4, progress=False).write({out!r})\n"
        f"print(*[m for m in ('scipy', 'matplotlib') if m in sys.modules])")
    assert len([n for n in os.listdir(out) if n.endswith(".png")]) == 14
    assert result.returncode == 0 and result.stdout.split() == [], \
        result.stdout + result.stderr[-2000:]


def test_a_camera_capture_and_its_folder_import_no_matplotlib(tmp_path):
    """A camera preset's capture writes its previews and its raw frames' grid
    (dopplertof.previews) without Matplotlib (pyplot alone: 1.2 s)."""
    out = str(tmp_path / "out")
    result = in_fresh_python(
        "import sys, dopplertof\ndopplertof.set_variant()\n"
        "from dopplertof.cameras import capture_camera, load_preset, load_scene_for_camera\n"
        "preset = load_preset('kinect-v2')\n"
        f"scene = load_scene_for_camera({SPHERE!r}, preset, (16, 12), {{'max_depth': '2'}})\n"
        f"capture_camera(scene, preset, spp=4, progress=False).write({out!r})\n"
        "print(*[m for m in ('scipy', 'matplotlib') if m in sys.modules])")
    assert result.returncode == 0 and result.stdout.split() == [], \
        result.stdout + result.stderr[-2000:]
    assert "raw.png" in os.listdir(out)


def test_lazy_names_are_what_they_name_after_every_module_is_imported():
    """Importing a submodule sets its package's attribute of that name to the module:
    a lazy name that is also a submodule's name (a function ``gradient`` in
    ``gradient.py``) would become the module once anything imported it. With every
    module imported first, each name of each lazy table is its submodule's object,
    or the submodule itself when it is named so and holds nothing of that name."""
    code = (f"import importlib, pkgutil, types, dopplertof\n"
            f"for m in pkgutil.walk_packages(dopplertof.__path__, 'dopplertof.'):\n"
            f"    importlib.import_module(m.name)\n"
            f"for p in {LAZY_PACKAGES!r}:\n"
            f"    pkg = importlib.import_module(p)\n"
            f"    for name, module in pkg._LAZY_EXPORTS.items():\n"
            f"        source = importlib.import_module(module, pkg.__package__)\n"
            f"        own = getattr(source, name, source)\n"
            f"        expected = source if module.lstrip('.') == name else own\n"
            f"        if getattr(pkg, name) is not expected or (expected is source\n"
            f"                and not isinstance(own, types.ModuleType)):\n"
            f"            print('wrong', p, name)\n"
            f"print('checked')")
    result = in_fresh_python(code)
    assert result.returncode == 0 and result.stdout.split() == ["checked"], \
        result.stdout + result.stderr[-2000:]


@pytest.mark.parametrize("argv,expected", [
    (["render", SPHERE, "-o", "{tmp}/x.png", "-P", "max_dept=3"], "did you mean 'max_depth'"),
    (["render", SPHERE, "-o", "{tmp}/x.png", "-P", "max_depth=abc"], "must be an integer"),
    (["render", SPHERE, "-o", "{tmp}/x.png", "--spp", "0"], "spp must be >= 1"),
    (["render", SPHERE, "-o", "{tmp}/x.png", "--seed", "-1"], "seed must be an integer in [0, 2^64)"),
    (["capture", SPHERE, "-o", "{tmp}/out", "-P", "hetro_frequency=1"], "did you mean"),
    (["capture", SPHERE, "-o", "{tmp}/out", "--spp", "0"], "spp must be >= 1"),
    (["precision", SPHERE, "-P", "w_gg=20"], "did you mean 'w_g'"),
    (["fmcw", SPHERE, "-o", "{tmp}/out", "--bandwidth", "0"], "bandwidth B must be > 0"),
    (["fmcw", SPHERE, "-o", "{tmp}/out", "--chirp-time", "-1"], "chirp_time T must be > 0"),
    (["fmcw", SPHERE, "-o", "{tmp}/out", "--bins", "1"], "bins M must be an integer >= 2"),
    (["fmcw", SPHERE, "-o", "{tmp}/out", "--wavelength", "150"], "wavelength must be within"),
    (["fmcw", SPHERE, "-o", "{tmp}/out", "--wavelength", "25000"], "wavelength must be within"),
    (["fmcw", SPHERE, "-o", "{tmp}/out", "-P", "max_dept=3"], "did you mean 'max_depth'"),
], ids=lambda v: " ".join(v[3:]) if isinstance(v, list) else None)
def test_usage_errors_come_before_mitsuba_loads(tmp_path, argv, expected):
    code, err, imported = cli_in_fresh_python(*[a.format(tmp=tmp_path) for a in argv])
    assert code == 2 and expected in err and err.count("\n") == 1, err
    assert imported == [], imported
    assert os.listdir(tmp_path) == []  # nothing written


def _kernels_of(run) -> set:
    """The hashes of the Dr.Jit kernels that ``run()`` launches (its kernel history)."""
    import drjit as dr

    dr.kernel_history()  # (clears what came before)
    flag = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        run()
        return {k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT}
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, flag)


def test_a_second_capture_with_other_offsets_and_frequencies_reuses_the_kernels():
    """Offsets and frequencies are opaque Dr.Jit values, not literals: the second
    capture compiles nothing new (a kernel costs 0.5-1.5 s to compile here)."""
    import dopplertof

    scene = dopplertof.load_file(SPHERE, res=8)

    def capture(**settings):
        return lambda: dopplertof.capture(scene, spp=4, progress=False, **settings)

    first = _kernels_of(capture())
    second = _kernels_of(capture(seed=3, hetero_frequency=2, unwrap_frequency=12,
                                 params={"w_g": 20, "hetero_offset": 0.3,
                                         "sensor_phase_offset": 0.2, "g_0": 0.5}))
    assert first and second <= first, (len(second - first), "new kernels")


def _scenes_of_one_shape():
    """Two scenes of each shape (a rotating body; a moving plane seen by a moving camera
    with a moving light) that differ in their keyframes and exposure windows."""
    import dopplertof
    from analytic import plane_scene

    cube = open(os.path.join(ROOT, "examples", "rotating_cube.xml")).read()
    turned = cube.replace('angle="30"', 'angle="12"').replace('angle="35.7296"', 'angle="21"')
    assert turned != cube
    yield (dopplertof.load_string(cube, res=8),
           dopplertof.load_string(turned, res=8).with_shutter(0.0004, 0.001))
    yield (dopplertof.load_dict(plane_scene(2.0, 30.0, res=4, camera_velocity=3.0,
                                            light_velocity=-2.0)),
           dopplertof.load_dict(plane_scene(2.7, -12.0, exposure=0.001, res=4,
                                            camera_velocity=5.0, light_velocity=-4.0))
           .with_shutter(0.0007, 0.001))


def test_a_second_capture_with_other_windows_and_motions_reuses_the_kernels():
    """Exposure windows, keyframes, the bodies' boxes and the groups per pixel are opaque
    Dr.Jit values, not literals (issue 40): a capture of another window, other motions
    and another spp (both at least one chunk of 8 groups), in a scene of the same shape,
    compiles nothing new."""
    import dopplertof

    for first_scene, second_scene in _scenes_of_one_shape():
        first = _kernels_of(lambda: dopplertof.capture(first_scene, spp=16, progress=False))
        second = _kernels_of(lambda: dopplertof.capture(second_scene, spp=32, seed=2,
                                                        progress=False))
        assert first and second <= first, (len(second - first), "new kernels")


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_second_make_demo_renders_nothing_when_its_outputs_are_up_to_date(tmp_path):
    """``make -n demo`` (what make would run) in a copy of the Makefile's world: the
    demo renders when demo_out is missing or older than a source, not otherwise."""
    for name, text in [("Makefile", open(os.path.join(ROOT, "Makefile")).read()),
                       ("pyproject.toml", ""), ("tools/ensure_llvm.sh", "exit 0\n"),
                       ("src/dopplertof/demo.py", ""),
                       ("src/dopplertof/data/cornell_demo.xml", ""),
                       (".venv/bin/python", ""), (".venv/.installed", "")]:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    os.chmod(tmp_path / ".venv/bin/python", 0o755)

    def renders() -> bool:
        out = subprocess.run(["make", "-n", "demo"], cwd=tmp_path, capture_output=True,
                             text=True, timeout=60)
        assert out.returncode == 0, out.stderr
        return "dopplertof demo" in out.stdout

    def age(name, seconds):  # set a file's time to ``seconds`` ago
        t = os.path.getmtime(tmp_path / ".venv/.installed") - seconds
        os.utime(tmp_path / name, (t, t))

    for name in ("pyproject.toml", "tools/ensure_llvm.sh", "src/dopplertof/demo.py",
                 "src/dopplertof/data/cornell_demo.xml"):
        age(name, 100)
    assert renders()  # no outputs yet
    (tmp_path / "demo_out").mkdir()
    (tmp_path / "demo_out/summary.json").write_text("{}")
    assert not renders()  # the second time: up to date
    age("demo_out/summary.json", 50)
    os.utime(tmp_path / "src/dopplertof/demo.py")  # a source changed since
    assert renders()
