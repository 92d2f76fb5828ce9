"""tools/campaign_rerun.py on synthetic rows: its classifier, its verdicts, and the inputs it
rebuilds from a row's case (no campaign is run here)."""

import math
import tomllib

from conftest import load_script

TRACEBACK = 'Traceback (most recent call last):\n  File "x.py", line 1\nKeyError: \'captures\'\n'


def test_each_outcome_gets_the_campaigns_category():
    tool = load_script("tools/campaign_rerun.py")
    one_line = "dopplertof: error: presets/P.toml: illuminator.power_w must be finite, got nan\n"
    assert tool.classify(0, "") == "ok"
    assert tool.classify(0, "dopplertof: warning: the sections are ignored\n") == "ok"
    assert tool.classify(2, one_line) == "clear"
    assert tool.classify(2, "dopplertof: warning: slow\n" + one_line) == "clear"
    assert tool.classify(2, one_line + "and a second line\n") == "unclear"
    assert tool.classify(1, one_line) == "unclear"
    assert tool.classify(2, TRACEBACK) == "traceback"
    assert tool.classify(0, TRACEBACK) == "traceback"
    assert tool.classify(-9, "") == "crash"
    assert tool.classify(137, "") == "crash"
    assert tool.classify(None, "", timed_out=True) == "hang"


def test_a_clear_row_now_ok_or_a_traceback_is_a_regression_and_wording_is_not():
    tool = load_script("tools/campaign_rerun.py")
    assert tool.verdict("clear", "clear") == "same"
    assert tool.verdict("clear", "unclear") == "wording"
    for now in ("ok", "traceback", "crash", "hang"):
        assert tool.verdict("clear", now) == "regression"
    assert tool.verdict("ok", "ok") == "same"
    for now in ("clear", "unclear", "traceback"):
        assert tool.verdict("ok", now) == "regression"
    assert tool.verdict("silent wrong", "clear") == "fixed"
    assert tool.verdict("unclear", "traceback") == "regression"
    assert tool.verdict("unclear", "unclear") == "changed"


def test_the_summary_counts_rows_before_and_now():
    tool = load_script("tools/campaign_rerun.py")
    rows = [{"id": "A1", "category": "clear"}, {"id": "A2", "category": "clear"},
            {"id": "A3", "category": "ok"}, {"id": "A4", "category": "ok"}]
    results = {"A1": {"status": "rerun", "now": "clear"}, "A2": {"status": "rerun", "now": "ok"},
               "A3": {"status": "covered", "by": "tests/x.py"},
               "A4": {"status": "not rebuilt", "why": "no script"}}
    summary = tool.summarise(rows, results)
    assert summary["before"] == {"clear": 2, "ok": 2}
    assert summary["now"] == {"clear": 1, "ok": 1, "covered": 1, "not rebuilt": 1}
    assert summary["verdicts"] == {"same": ["A1"], "regression": ["A2"]}


def test_rows_with_signals_or_two_commands_at_once_are_not_rerun():
    tool = load_script("tools/campaign_rerun.py")
    assert tool.covered_by("interrupt: fmcw", "dopplertof fmcw s.xml -o x # INT at render")
    assert tool.covered_by("output: fmcw", "dopplertof fmcw a.xml -o c & dopplertof fmcw a.xml -o c")
    assert tool.covered_by("camera preset TOML", "dopplertof cameras presets/PR01.toml") is None


def test_a_preset_case_becomes_that_one_edit(tmp_path):
    tool = load_script("tools/campaign_rerun.py")
    presets = tool.ROOT / "src" / "dopplertof" / "cameras" / "presets"
    shipped = tomllib.loads((presets / "azure-kinect.toml").read_text())

    def edited(case):
        return tomllib.loads(tool.preset_text(case, presets).decode())

    assert edited("illuminator.power_w = -43.7")["illuminator"]["power_w"] == -43.7
    assert edited('illuminator.power_w = "43.7" (string)')["illuminator"]["power_w"] == "43.7"
    pitch = edited("reconstruction.min_range_m = 10 > max_range_m = 5.79")
    assert pitch["reconstruction"]["min_range_m"] == 10
    assert pitch["reconstruction"]["max_range_m"] == shipped["reconstruction"]["max_range_m"]
    fov = edited("illuminator.fov_deg = [20, 20] (narrower than the 75 deg camera): capture")
    assert fov["illuminator"]["fov_deg"] == [20, 20]
    assert edited("frames[0].start_s = -0.001")["frames"][0]["start_s"] == -0.001
    assert edited("frames[0].start_s = -0.001")["frames"][1:] == shipped["frames"][1:]
    assert "illuminator" not in edited("[illuminator] section removed, auto_exposure = false")
    assert tool.preset_text("UTF-8 BOM at the start of the file", presets).startswith(b"\xef\xbb\xbf")
    assert tool.preset_text("something no edit describes", presets) is None


def test_an_fmcw_case_becomes_that_one_edit_of_the_street_scene():
    tool = load_script("tools/campaign_rerun.py")
    street = (tool.ROOT / "examples" / "fmcw_street.xml").read_text()
    assert '<float name="fmcw_bandwidth" value="4e9"/>' in tool.fmcw_xml(
        "fmcw_bandwidth = 4e9 (Hz written for GHz)", street)
    assert '<string name="fmcw_beam" value=""/>' in tool.fmcw_xml("fmcw_beam = '' (empty)", street)
    both = tool.fmcw_xml("fmcw_beam_intensity = 0 (collimated)", street)
    assert '<float name="fmcw_beam_intensity" value="0"/>' in both
    assert '<string name="fmcw_beam" value="collimated"/>' in both
    assert '<float name="fmcw_bins" value="256.5"/>' in tool.fmcw_xml("fmcw_bins as <float> 256.5", street)
    assert tool.fmcw_xml("the street scene as shipped (B 4 GHz)", street) == street


def test_an_api_case_becomes_its_expression():
    tool = load_script("tools/campaign_rerun.py")
    assert tool.api_expression("fmcw('fmcw_street.xml') (a path)") == "fmcw('fmcw_street.xml')"
    assert tool.api_expression("Chirp(chirp_time=1e-12) (shorter than any round trip)") == \
        "Chirp(chirp_time=1e-12)"
    assert tool.api_expression("capture_camera(..., ambient_irradiance=True)") == \
        "capture_camera(sphere, 'azure-kinect', spp=4, ambient_irradiance=True)"


def test_a_reviewed_change_is_not_a_regression_and_argparse_usage_is_one_error():
    tool = load_script("tools/campaign_rerun.py")
    rows = [{"id": "A1", "category": "ok"}, {"id": "A2", "category": "ok"}]
    results = {"A1": {"status": "rerun", "now": "clear"}, "A2": {"status": "rerun", "now": "clear"}}
    summary = tool.summarise(rows, results, {"A1": "a new check refuses it"})
    assert summary["verdicts"] == {"reviewed": ["A1"], "regression": ["A2"]}
    assert results["A1"]["reviewed"] == "a new check refuses it"
    usage = ("usage: dopplertof fmcw [-h] [-o OUT]\n                       [--bins N]\n"
             "dopplertof fmcw: error: argument --bins: invalid int value: '2.5'\n")
    assert tool.classify(2, usage) == "clear"
    assert tool.classify(2, usage + "a second error line\n") == "unclear"


def test_a_dataset_config_case_names_its_preset_edit(tmp_path):
    tool = load_script("tools/campaign_rerun.py")
    presets = tool.ROOT / "src" / "dopplertof" / "cameras" / "presets"
    cfg = tmp_path / "cfg" / "dc"
    cfg.mkdir(parents=True)
    text = tool.dc_config("render.camera = a preset file with optics.pixel_pitch_um = 1e300 (PR32)",
                          cfg, presets)
    assert tomllib.loads(text)["render"]["camera"] == "PR32.toml"
    assert tomllib.loads((cfg / "PR32.toml").read_text())["optics"]["pixel_pitch_um"] == 1e300
    grazing = tomllib.loads(tool.dc_config("render.grazing_deg = nan", cfg, presets))["render"]["grazing_deg"]
    assert math.isnan(grazing)
    tool.dc_config("render.camera = 'mine.toml' (relative to the config's folder)", cfg, presets)
    assert tool.dc_config("preset file mine.toml edited (power_w 43.7 -> 40) after DC06's run", cfg,
                          presets) == ""
    assert tomllib.loads((cfg / "mine.toml").read_text())["illuminator"]["power_w"] == 40


def test_verify_naming_the_damaged_shard_is_clear_and_the_damages_touch_only_their_file(tmp_path):
    tool = load_script("tools/campaign_rerun.py")
    report = "verify: 2 shards, 1 complete; a rerun would render again: shard_00001.h5\n"
    assert tool.verify_category(1, report, "") == "clear"
    assert tool.verify_category(1, "verify: something is wrong\n", "") == "unclear"
    assert tool.verify_category(0, "verify: 2 shards, 2 complete\n", "") == "ok"
    assert tool.verify_category(1, report, TRACEBACK) == "traceback"
    for name in ("shard_00000.h5", "shard_00001.h5"):
        (tmp_path / name).write_bytes(bytes(range(16)) + name.encode())
    tool.SHARD_DAMAGES["flip_signature"](tmp_path)
    assert (tmp_path / "shard_00001.h5").read_bytes()[3] == 3 ^ 0xFF
    assert (tmp_path / "shard_00000.h5").read_bytes()[3] == 3
    tool.SHARD_DAMAGES["swap"](tmp_path)
    assert (tmp_path / "shard_00000.h5").read_bytes().endswith(b"shard_00001.h5")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shard_00000.h5", "shard_00001.h5"]


def test_a_clear_line_names_a_path_option_or_key_of_its_row():
    tool = load_script("tools/campaign_rerun.py")
    names = tool.row_names("dopplertof cameras presets/PR01.toml", "illuminator.power_w = nan")
    assert {"presets/PR01.toml", "PR01.toml", "illuminator.power_w", "power_w"} <= names
    assert "cameras" not in names and "dopplertof" not in names
    assert tool.classify(2, "dopplertof: error: illuminator.power_w must be finite\n", names=names) == "clear"
    assert tool.classify(2, "dopplertof: error: something is wrong\n", names=names) == "unclear"
    flags = tool.row_names("dopplertof fmcw s.xml -D res=16 --bins 2.5 -o fo_FO08", "--bins 2.5")
    assert {"--bins", "res", "fo_FO08"} <= flags and "2.5" not in flags and "16" not in flags
