"""The I/Q receiver as a scene key: ``fmcw_iq`` in the <integrator>, as every other FMCW
setting; the command's --iq / --no-iq over -P fmcw_iq over the scene's, over the
default (a real receiver)."""

import json

import numpy as np
import pytest

import dopplertof
from dopplertof.cli import main
from test_campaign_fmcw import SPHERE, _digests, _refused, _sphere_with


def _frame(tmp_path, name, scene, *options):
    out = tmp_path / name
    assert main(["fmcw", scene, "-o", str(out), "--spp", "2", "-D", "res=4", "--bins", "64",
                 "-P", "max_depth=2", *options]) == 0
    return out


def _arrays(folder) -> dict:
    """Every array the frame wrote (summary.json holds its run time: not compared)."""
    return {k: v for k, v in _digests(folder).items() if k.endswith(".npy")}


def test_the_scene_key_gives_the_option_s_frame_bitwise(tmp_path):
    """fmcw_iq = true in the scene's <integrator> writes the same arrays, bitwise, as
    --iq on the scene without it; --no-iq over the key, and -P fmcw_iq=false, write the
    real receiver's frame, and the key reads back in the settings."""
    keyed = _sphere_with(tmp_path, '<boolean name="fmcw_iq" value="true"/>', "iq.xml")
    assert dopplertof.load_file(keyed, {"res": "4"}).modality_settings["fmcw"].iq is True
    assert dopplertof.load_file(SPHERE, {"res": "4"}).modality_settings["fmcw"].iq is False
    by_option = _frame(tmp_path, "option", SPHERE, "--iq")
    by_key = _frame(tmp_path, "key", keyed)
    assert _arrays(by_key) == _arrays(by_option)
    assert np.load(by_key / "spectrum.npy").shape == (4, 4, 2, 128)  # two-sided: 2 M bins
    summary = json.loads((by_key / "summary.json").read_text())
    assert summary["chirp"]["receiver"].startswith("I/Q")
    real = _frame(tmp_path, "real", SPHERE)
    for name, options in (("no_iq", ("--no-iq",)), ("p_false", ("-P", "fmcw_iq=false"))):
        assert _arrays(_frame(tmp_path, name, keyed, *options)) == _arrays(real)
    assert _arrays(_frame(tmp_path, "p_true", SPHERE, "-P", "fmcw_iq=1")) == \
        _arrays(by_option)


@pytest.mark.parametrize("value", ["maybe", "2"])
def test_a_bad_value_is_one_line_naming_the_file_and_key(tmp_path, capsys, value):
    scene = _sphere_with(tmp_path, f'<string name="fmcw_iq" value="{value}"/>')
    out = tmp_path / "out"
    code = main(["fmcw", scene, "-o", str(out), "--spp", "1", "-D", "res=4"])
    _refused(capsys, code, "fmcw_iq", f"{scene}:14:", repr(value))
    assert not out.exists()
    with pytest.raises(dopplertof.SceneError, match="fmcw_iq"):
        dopplertof.load_file(scene)
