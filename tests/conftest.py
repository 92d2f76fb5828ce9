import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(__file__))  # tests/analytic.py

FIXTURES = os.path.join(os.path.dirname(__file__), "fixtures")
#: the repository's root (benchmarks/, tools/ and examples/ hold scripts the tests load)
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PUBLISHED = os.path.join(FIXTURES, "cornell_box_moving.xml")


@pytest.fixture(autouse=True)
def llvm_variant():
    """Every test starts (and ends) with the LLVM RGB variant set."""
    import dopplertof

    dopplertof.set_variant("llvm_ad_rgb")
    yield
    import mitsuba as mi

    if mi.variant() != "llvm_ad_rgb":
        dopplertof.set_variant("llvm_ad_rgb")
    # a dataset's kept-alive kinds (dataset/structure.py) would make every later test's
    # calls over shapes and BSDFs trace their instances too (a fit: 2 s alone, 16 s after)
    structure = sys.modules.get("dopplertof.dataset.structure")
    if structure is not None:
        structure.release_kinds()


def render_killed_then_resumed(monkeypatch, scene, checkpoint, die_after, **render_args):
    """Render with a checkpoint, one pass per chunk, killed (KeyboardInterrupt) right
    after the ``die_after``-th checkpoint was saved; then the same render again, which
    resumes from the checkpoint. Returns the resumed image."""
    import dopplertof

    R = sys.modules["dopplertof.render"]  # the module (dopplertof.render is the function)
    calls = {"n": 0}
    original = R.Checkpoint.save

    def save_then_die(self, *args):
        original(self, *args)
        calls["n"] += 1
        if calls["n"] == die_after:
            raise KeyboardInterrupt

    monkeypatch.setattr(R.Checkpoint, "save", save_then_die)
    with pytest.raises(KeyboardInterrupt):
        dopplertof.render(scene, pass_chunks=1, checkpoint=checkpoint, **render_args)
    monkeypatch.setattr(R.Checkpoint, "save", original)
    assert os.path.exists(checkpoint)
    return dopplertof.render(scene, pass_chunks=1, checkpoint=checkpoint, **render_args)


def load_script(relative_path: str):
    """A script of the repository (``benchmarks/reference.py`` and the like, not part of
    the package) loaded as a module."""
    import importlib.util

    name = os.path.splitext(os.path.basename(relative_path))[0]
    spec = importlib.util.spec_from_file_location(name, os.path.join(ROOT, relative_path))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
