"""The CUDA verification suite (marker ``gpu``; issue 28): every test takes its Mitsuba
variant as a parameter, ``llvm_ad_rgb`` always and ``cuda_ad_rgb`` where a CUDA device
is present (skipped with the reason elsewhere), so that the bodies run on every CPU
machine and only the variant changes on a GPU. ``tools/gpu_check.sh`` runs them there.

Statistics: the CUDA-against-LLVM comparisons render independent seeds in each variant
(the candidate's seeds are not the reference's, so LLVM against LLVM is the same test)
and estimate every standard error from the spread over those seeds, never from a fixed
tolerance. With n = 16 seeds a side, the image means' Welch t (15 degrees of freedom
taken, conservative) and each time-sampling method's t against its quadrature are
within MEAN_Z_BOUND = 6.44: 9 comparisons per variant at a false-failure rate of 1e-4
for the file (tests/bounds.py; docs/testing.md). The root mean square of the per-pixel
t values stays below 1.5, measured LLVM against LLVM over 20 seed sets: the published
scene's 192 pixels 1.005 +- 0.043 (largest 1.071), the plane's 64 (8x8) 1.075 +- 0.072
(1.223), the splat against the importance film's 64 1.046 +- 0.084 (1.221): 1.5 is at
least 5.4 of those spreads above. A bias of a tenth of a standard error in every pixel
is not caught; a black, NaN or shifted image is. The numbers go into the JUnit report as properties
(``agreement_<scene>_*``), where ``tools/gpu_report.py`` reads them.
"""

import ast
import ctypes
import glob
import math
import os

import numpy as np
import pytest

import dopplertof
from analytic import plane_scene, reference
from bounds import student_bound
from conftest import PUBLISHED, render_killed_then_resumed

pytestmark = pytest.mark.gpu

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: the published scene in the shared fixtures: beside the repository or, where only the
#: repository travels (to a GPU machine), inside it; the first where neither is present
SHARED_CANDIDATES = [os.path.join(base, "shared", "fixtures", "published",
                                  "cornell_box_moving.xml")
                     for base in (os.path.dirname(ROOT), ROOT)]
SHARED_PUBLISHED = next((p for p in SHARED_CANDIDATES if os.path.exists(p)),
                        SHARED_CANDIDATES[0])
LLVM, CUDA = "llvm_ad_rgb", "cuda_ad_rgb"
#: seeds per variant in the agreement tests, and the bounds (module docstring)
SEEDS, MEAN_Z_BOUND, RMS_Z_BOUND = 16, student_bound(1e-4, 9, 15), 1.5


def cuda_device_problem():
    """Why no CUDA variant can run here (None: an NVIDIA device node and the CUDA driver
    library are present). Looked up once, from files only: Dr.Jit's CUDA backend is not
    started, so the LLVM tests of the same process run as they would without it."""
    if not glob.glob("/dev/nvidia[0-9]*"):
        return "no NVIDIA device (/dev/nvidia0, ...) on this machine"
    try:
        ctypes.CDLL("libcuda.so.1")
    except OSError as exc:
        return f"an NVIDIA device but no CUDA driver library (libcuda.so.1: {exc})"
    return None


NO_CUDA = cuda_device_problem()
VARIANTS = [LLVM, pytest.param(CUDA, marks=pytest.mark.skipif(
    NO_CUDA is not None, reason=f"cuda_ad_rgb: {NO_CUDA}"))]


@pytest.fixture(params=VARIANTS)
def variant(request):
    """The variant under test, set (conftest sets LLVM back afterwards)."""
    dopplertof.set_variant(request.param)
    return request.param


# ---- Scenes, each loaded in the variant set when it is called ----

def published(res=(16, 12), path=PUBLISHED):
    """The published scene: the shared fixture (skipped where absent) or, by default, the
    tests' copy of it (tests/fixtures, the same file)."""
    if not os.path.exists(path):
        pytest.skip(f"the published scene is absent ({path})")
    return dopplertof.load_file(path, {"resx": res[0], "resy": res[1]})


def moving_plane(res=4, **integrator):
    return dopplertof.load_dict(plane_scene(4.0, 30.0, spp=64, res=res,
                                            integrator={"hetero_frequency": 1.0, **integrator}))


#: the agreement tests' scenes (the plane at 8x8: 64 pixels in the RMS of their t values)
SCENES = {"published": lambda: published(path=SHARED_PUBLISHED),
          "moving_plane": lambda: moving_plane(res=8)}


# ---- Agreement in standard errors from independent seeds ----

def seed_renders(variant, make_scene, seeds, spp, params=None):
    """(n, H, W) float64: the channel mean of one render per seed, in ``variant``."""
    dopplertof.set_variant(variant)
    scene = make_scene()
    return np.stack([dopplertof.render(scene, spp=spp, seed=s, params=params).mean(axis=-1)
                     for s in seeds]).astype(np.float64)


def agreement(ref, got) -> dict:
    """Welch's t of the two stacks' image means and the RMS and largest per-pixel t."""
    n, m = len(ref), len(got)

    def t_value(a, b):
        se = np.sqrt(a.var(axis=0, ddof=1) / n + b.var(axis=0, ddof=1) / m)
        return (b.mean(axis=0) - a.mean(axis=0)) / np.where(se > 0, se, np.inf)

    mean_t = float(t_value(ref.mean(axis=(1, 2)), got.mean(axis=(1, 2))))
    pixel_t = t_value(ref, got)
    finite = bool(np.all(np.isfinite(got)))
    return {"mean_z": mean_t, "rms_z": float(np.sqrt(np.mean(pixel_t**2))),
            "max_z": float(np.max(np.abs(pixel_t))), "seeds": n, "finite": finite,
            "image_mean": float(got.mean()), "reference_mean": float(ref.mean())}


@pytest.mark.parametrize("scene_name", sorted(SCENES))
def test_variant_agrees_with_llvm_within_noise(variant, scene_name, record_property):
    make_scene = SCENES[scene_name]
    ref = seed_renders(LLVM, make_scene, range(SEEDS), spp=16)
    got = seed_renders(variant, make_scene, range(1000, 1000 + SEEDS), spp=16)
    stats = agreement(ref, got)
    for key, value in stats.items():
        record_property(f"agreement_{scene_name}_{key}", value)
    assert stats["finite"] and np.abs(ref).max() > 0
    assert abs(stats["mean_z"]) < MEAN_Z_BOUND, stats
    assert stats["rms_z"] < RMS_Z_BOUND, stats


# ---- Same seed, same image; resumed, the same image too ----

def test_same_seed_same_image_bitwise(variant):
    scene = published()
    a = dopplertof.render(scene, spp=32, seed=5)
    assert np.array_equal(a, dopplertof.render(scene, spp=32, seed=5))
    assert np.array_equal(a, dopplertof.render(scene, spp=32, seed=5, pass_chunks=1))
    assert np.all(np.isfinite(a)) and not np.array_equal(a, dopplertof.render(scene, spp=32,
                                                                              seed=6))


def test_checkpoint_resume_is_bitwise(variant, tmp_path, monkeypatch):
    scene = published(res=(12, 10))
    straight = dopplertof.render(scene, spp=64, seed=4)
    resumed = render_killed_then_resumed(monkeypatch, scene, tmp_path / "r.ckpt", 2,
                                         spp=64, seed=4)
    assert np.array_equal(resumed, straight)


# ---- Every time-sampling method against the plane's quadrature ----

@pytest.mark.parametrize("method", ["uniform", "stratified", "antithetic",
                                    "antithetic_mirror", "analytic"])
def test_every_time_sampling_method_matches_its_quadrature(variant, method):
    """Sampled methods against the exact value, ``analytic`` against the quadrature of
    its own approximation (it is biased), each within MEAN_Z_BOUND standard errors over
    seeds and 1e-5 of the value (float32 rounding: ``analytic`` varies by 3e-11 over
    seeds, its film positions the only randomness, and is 2.5e-6 off on LLVM)."""
    from analytic import analytic_approximation

    expected = (analytic_approximation(4.0, 30.0, hetero_frequency=1.0) if method == "analytic"
                else reference(4.0, 30.0, hetero_frequency=1.0))
    values = seed_renders(variant, lambda: moving_plane(res=1), range(SEEDS), spp=64,
                          params={"time_sampling_method": method})[:, 0, 0]
    error = values.std(ddof=1) / math.sqrt(len(values))
    assert np.all(np.isfinite(values)) and error > 0
    assert abs(values.mean() - expected) < MEAN_Z_BOUND * error + 1e-5 * abs(expected), (
        values.mean(), expected, error)


# ---- A capture, the splat film, a derivative, a camera preset ----

def test_capture_velocity_within_2_percent(variant):
    result = dopplertof.capture(moving_plane(), spp=256, seed=0, progress=False)
    assert np.all(np.isfinite(result.velocity))
    assert np.max(np.abs(result.velocity / result.velocity_gt - 1)) < 0.02
    assert np.allclose(result.velocity_gt, 30.0, rtol=0.01)


def test_splat_film_matches_the_importance_film_within_noise(variant):
    """Both films estimate the same filtered pixel values (tent filter): per pixel within
    noise, and the splat film bitwise the same whatever the passes."""
    def plane_with(film):
        def make():
            scene = plane_scene(4.0, 30.0, spp=64, res=8, integrator={
                "hetero_frequency": 1.0, "film_sampling": film})
            scene["sensor"]["film"]["rfilter"] = {"type": "tent"}
            return dopplertof.load_dict(scene)
        return make

    splat = seed_renders(variant, plane_with("splat"), range(SEEDS), spp=16)
    importance = seed_renders(variant, plane_with("importance"), range(50, 50 + SEEDS), spp=16)
    stats = agreement(importance, splat)
    assert abs(stats["mean_z"]) < MEAN_Z_BOUND and stats["rms_z"] < RMS_Z_BOUND, stats
    scene = plane_with("splat")()
    assert np.array_equal(dopplertof.render(scene, seed=3),
                          dopplertof.render(scene, seed=3, pass_chunks=1))


def test_derivative_render_matches_the_quadrature_derivative(variant):
    """d(pixel)/d(body velocity) of the plane within 2% of the quadrature's (the
    estimate's spread over seeds is 0.04% at 1024 spp: tests/test_differentiable.py)."""
    from dopplertof.diff import DifferentiableScene, render_derivatives

    scene = DifferentiableScene(dopplertof.load_dict(plane_scene(
        2.0, 10.0, spp=1024, integrator={"hetero_frequency": 1.0})))
    got = render_derivatives(scene, ["body0.vz"], spp=1024, seed=0).tangents["body0.vz"]
    h = 0.1
    expected = (reference(2.0, 10.0 + h, hetero_frequency=1.0)
                - reference(2.0, 10.0 - h, hetero_frequency=1.0)) / (2 * h)
    assert abs(got[0, 0, 0] / expected - 1) < 0.02, (got, expected)


PLANE_AT_3M = """<scene version="3.0.0">
    <integrator type="dopplertof"><integer name="max_depth" value="2"/></integrator>
    <sensor type="perspective"><float name="fov" value="6"/>
        <transform name="to_world"><lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/>
        </transform>
        <sampler type="independent"><integer name="sample_count" value="8"/></sampler>
        <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/>
            <rfilter type="box"/></film>
    </sensor>
    <emitter type="point"><point name="position" x="0" y="0" z="0"/>
        <rgb name="intensity" value="10"/></emitter>
    <shape type="rectangle"><bsdf type="diffuse"/>
        <transform name="to_world"><scale value="50"/><rotate y="1" angle="180"/>
            <translate z="3"/></transform>
    </shape>
</scene>
"""


def test_camera_preset_capture_measures_the_plane(variant, tmp_path):
    from dopplertof.cameras.capture import capture_camera
    from dopplertof.cameras.scene_view import load_scene_for_camera
    from dopplertof.cameras.preset import load_preset

    path = tmp_path / "plane.xml"
    path.write_text(PLANE_AT_3M)
    preset = load_preset("pmd-argos3d-p320")
    scene = load_scene_for_camera(path, preset, resolution=(6, 5))
    result = capture_camera(scene, preset, spp=8, seed=0, progress=False)
    assert result.raw.shape == (4, 5, 6)
    # the plane at z = 3 m within 5 predicted standard deviations (shot noise)
    depth_std = np.sqrt(result.reconstruction.depth_variance)
    assert np.all(np.abs(result.reconstruction.depth_z - 3.0) < 5 * depth_std + 1e-3)


# ---- Every scene query behind one interface (the OptiX fallback's swap) ----

SCENE_QUERY_METHODS = {"ray_intersect", "ray_intersect_preliminary", "ray_test"}


def test_every_scene_query_goes_through_scene_queries():
    """No module calls a Mitsuba scene's ray query but bodies.SceneQueries (the bounding
    box's own ray_intersect in bodies.box_intersect is not a scene's)."""
    calls = []

    def visit(node, path, owner):  # owner: the outermost function or class around it
        if owner is None and isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            owner = node.name
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr in SCENE_QUERY_METHODS):
            calls.append((path, owner, node.func.attr))
        for child in ast.iter_child_nodes(node):
            visit(child, path, owner)

    for folder, _, files in os.walk(os.path.join(ROOT, "src", "dopplertof")):
        for name in (f for f in files if f.endswith(".py")):
            path = os.path.join(folder, name)
            visit(ast.parse(open(path, encoding="utf-8").read()), path, None)
    outside = [c for c in calls if c[1] not in ("SceneQueries", "box_intersect")]
    assert calls and not outside, outside


def test_a_swapped_scene_queries_traces_every_scene_and_changes_nothing(monkeypatch):
    from dopplertof.scene import bodies

    scene = published(res=(8, 6))
    before = dopplertof.render(scene, spp=16, seed=2)
    seen = set()

    class Recording(bodies.SceneQueries):
        def preliminary(self, scene, ray, coherent, active):
            seen.add(id(scene))
            return super().preliminary(scene, ray, coherent, active)

        def blocked(self, scene, ray, active):
            seen.add(id(scene))
            return super().blocked(scene, ray, active)

    monkeypatch.setattr(bodies, "QUERIES", Recording())
    after = dopplertof.render(scene, spp=16, seed=2)
    assert seen == {id(scene.static), *(id(b.scene) for b in scene.bodies)}
    assert np.array_equal(before, after)


def test_one_scene_per_kernel_agrees_with_llvm_within_noise(variant, record_property):
    """The OptiX fallback (bodies.one_scene_per_kernel) against LLVM's fused renders,
    as the agreement test; on LLVM also bitwise its fused image (measured so)."""
    from dopplertof.scene import bodies

    ref = seed_renders(LLVM, published, range(SEEDS), spp=16)
    with bodies.one_scene_per_kernel():
        got = seed_renders(variant, published, range(1000, 1000 + SEEDS), spp=16)
        alone = dopplertof.render(published(), spp=16, seed=3)
    stats = agreement(ref, got)
    for key, value in stats.items():
        record_property(f"agreement_published_one_scene_per_kernel_{key}", value)
    assert stats["finite"] and abs(stats["mean_z"]) < MEAN_Z_BOUND, stats
    assert stats["rms_z"] < RMS_Z_BOUND, stats
    assert isinstance(bodies.QUERIES, bodies.SceneQueries) and bodies.QUERIES.dispatch
    if variant == LLVM:
        assert np.array_equal(alone, dopplertof.render(published(), spp=16, seed=3))
