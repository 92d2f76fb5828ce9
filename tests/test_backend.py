"""libLLVM selection: never let Dr.Jit load a libLLVM that aborts the process."""

import os
import subprocess
import sys

import pytest

from dopplertof import backend


@pytest.mark.parametrize("name,major", [
    ("libLLVM-15.so", 15), ("libLLVM.so.19.1", 19), ("libLLVM-14.0.6.so.1", 14),
    ("libLLVM-17.so.1", 17), ("libLLVM.dylib", None),
])
def test_version_from_file_name(name, major):
    assert backend.llvm_major_version("/x/" + name) == major


def test_found_library_is_usable():
    path = backend.find_libllvm()
    assert path is not None and backend.llvm_major_version(path) >= backend.MIN_LLVM_MAJOR


def test_bad_user_library_is_refused(tmp_path, monkeypatch):
    old = tmp_path / "libLLVM-15.so"
    old.write_bytes(b"")
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(old))
    with pytest.raises(backend.BackendError, match="LLVM 15, which crashes Dr.Jit"):
        backend.ensure_libllvm()
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(tmp_path / "missing.so"))
    with pytest.raises(backend.BackendError, match="does not exist"):
        backend.ensure_libllvm()


def test_cli_reports_a_bad_libllvm_in_one_line(tmp_path):
    old = tmp_path / "libLLVM-14.so"
    old.write_bytes(b"")
    env = dict(os.environ, DRJIT_LIBLLVM_PATH=str(old))
    scene = os.path.join(os.path.dirname(__file__), "fixtures", "cornell_box_moving.xml")
    proc = subprocess.run([sys.executable, "-m", "dopplertof.cli", "render", scene, "-o",
                           str(tmp_path / "x.npy")], env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "crashes Dr.Jit" in proc.stderr
    assert "apt-get install libllvm19" in proc.stderr


def test_scalar_and_unknown_variants_are_refused():
    with pytest.raises(backend.BackendError, match="not supported"):
        backend.set_variant("scalar_rgb")
    with pytest.raises(backend.BackendError, match="unknown variant"):
        backend.set_variant("vulkan_rgb")
