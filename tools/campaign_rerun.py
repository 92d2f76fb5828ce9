#!/usr/bin/env python
"""Rerun a fault campaign (a TSV of id, surface, case, command, expected, observed, category)
against the current source and compare each row's outcome with the recorded category.

    nice -n 15 tools/campaign_rerun.py ../shared/reliability/campaign-2026-12-07.tsv \
        --scratch /tmp/rerun -o campaign_rerun.json

For each row it rebuilds the inputs the line describes (the scenes, the preset copies with the
one edit of the ``case`` column, the FMCW scene copies, the small datasets and captures the
commands read), runs the command with ``dopplertof`` bound to this checkout's CLI and a
per-row timeout, and classifies the result as the campaign did:

    ok         exit 0
    clear      exit 2, one stderr line (warnings aside), no traceback
    unclear    any other non-zero exit without a traceback, or several error lines
    traceback  a Python traceback on stderr
    crash      killed by a signal (negative exit status, or 128 + signal from a shell)
    hang       still running at the timeout

A row that was 'clear' and is now ok, traceback, crash or hang is a regression, and so is a
row that was 'ok' and now is anything else; a row that was 'clear' and is now 'unclear' is
listed as a wording change to read. Rows the tool cannot rebuild from the line (signals sent
mid-run, two commands at once, an external Dask scheduler, damaged shards made by a script
the TSV does not hold, read-only or full file systems) are listed as 'covered' with the tests
of their surface, or 'not rebuilt: WHY'; they are never guessed.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import tomllib
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CATEGORIES = ("ok", "clear", "unclear", "traceback", "crash", "hang")
RECORDED = ("ok", "clear", "unclear", "silent wrong", "data loss")
CLI = "import sys; from dopplertof.cli import main; sys.exit(main())"

# Rows whose faults (signals, processes killed, two runs at once, an external scheduler, damaged
# shards, full or read-only file systems) the suite reproduces: surface prefix -> the tests.
COVERED = (
    ("interrupt: capture --camera --checkpoint", "tests/test_capture_checkpoint.py"),
    ("interrupt: capture", "tests/test_interrupt.py::test_sigint_at_any_moment_of_a_render_is_one_line, "
     "tests/test_faults_outputs.py::test_a_run_killed_while_writing_leaves_the_old_set_and_its_leftovers_go"),
    ("interrupt: fmcw", "tests/test_interrupt.py::test_sigint_at_any_moment_of_a_render_is_one_line, "
     "tests/test_faults_outputs.py::test_a_run_killed_while_writing_leaves_the_old_set_and_its_leftovers_go"),
    ("interrupt: dataset export", "tests/test_campaign_dataset.py::test_a_killed_exports_staging_folder_is_"
     "removed_by_the_next, ::test_sigterm_during_an_export_says_so_in_one_line"),
    ("interrupt: dataset", "tests/test_interrupt.py::test_ctrl_c_while_the_local_cluster_starts_stops_the_run, "
     "::test_a_driver_killed_while_its_workers_spawn_leaves_nothing_on_the_terminal"),
    ("dask scheduler", "tests/test_cluster_faults.py, tests/test_campaign_dataset.py::"
     "test_a_cancelled_shard_task_writes_nothing"),
    ("concurrency", "tests/test_campaign_dataset.py::test_a_folder_written_meanwhile_is_refused_in_one_line"),
    ("full disk", "tests/test_faults_outputs.py::test_a_full_disk_mid_capture_leaves_the_previous_capture_"
     "untouched, tests/test_campaign_dataset.py::test_an_export_onto_a_full_disk_names_the_file"),
)
# Inputs the line names but does not describe well enough to rebuild: token -> why.
UNBUILT = {
    "torfchk.py": "the checking script is not in the TSV",
    "flatchk.py": "the checking script is not in the TSV",
    "ds_fail": "a dataset with a failed sample needs a failing worker (tests/test_campaign_dataset.py::"
               "test_an_export_of_a_dataset_with_a_failed_sample_names_it)",
    "ds_flat": "a 512x424 kinect-v2 dataset (too slow for a rerun on 2 cores)",
    "dmg_SH09_b": "made by shardcase.py",
    "fitspin": "the spinning-sphere scene is not in the TSV",
    "ro/": "a read-only mount (root ignores file modes)",
}


def classify(rc: int | None, stderr: str, timed_out: bool = False, names=None) -> str:
    """The campaign's category of one command's outcome; ``names``: the words of the row
    (paths, options, keys) of which a clear error line names at least one (None: any line)."""
    if timed_out:
        return "hang"
    if "Traceback (most recent call last)" in stderr:
        return "traceback"
    if rc is None or rc < 0 or rc >= 128:
        return "crash"
    if rc == 0:
        return "ok"
    lines, usage = [], False
    for line in stderr.splitlines():
        # argparse's usage block (a "usage:" line and its indented continuation) precedes
        # its one error line
        usage = line.startswith("usage:") or (usage and line.startswith(" "))
        if line.strip() and not usage and "warning" not in line.lower():
            lines.append(line)
    if rc != 2 or len(lines) != 1:
        return "unclear"
    line = lines[0].lower().replace("_", "-")
    return "clear" if names is None or any(n.lower().replace("_", "-") in line for n in names) else "unclear"


GENERIC = {"dopplertof", "capture", "fmcw", "cameras", "dataset", "export", "show", "verify", "fit",
           "bash", "timeout", "python", "quiet", "true", "false", "none"}


def row_names(command: str, case: str) -> set[str]:
    """The words a clear error line of the row may name: the command's paths (and their file
    names), options and -D/-P parameter names, and the keys its case names (with their parts:
    fmcw_bins names bins; '_' and '-' count as one)."""
    words = set()
    for word in re.findall(r"[^\s'\"=;&|<>(),]+", command + " " + case):
        word = word.strip(".:[]{}")
        if re.fullmatch(r"-[A-Za-z]", word):
            words.add(word + " ")
        if len(word) < 3 or word.lower() in GENERIC or re.fullmatch(r"[-+\d.ex]+", word):
            continue
        words.update({word, word.lstrip("-"), os.path.basename(word.rstrip("/"))})
        if re.fullmatch(r"[\w.]+", word):
            words.update(part for part in word.split(".") if len(part) >= 3)
            words.update(part for part in re.split(r"[._]", word) if len(part) >= 4)
    return {w for w in words if len(w) >= 3 and w.lower() not in GENERIC}


def verdict(recorded: str, now: str) -> str:
    """'regression', 'wording' (clear -> unclear), 'fixed', 'changed' or 'same'."""
    if now in ("traceback", "crash", "hang"):
        return "regression"
    if recorded == "clear":
        return {"clear": "same", "unclear": "wording"}.get(now, "regression")
    if recorded == "ok":
        return "same" if now == "ok" else "regression"
    return "fixed" if now in ("ok", "clear") else "changed"


def covered_by(surface: str, command: str) -> str | None:
    """The tests that cover a row the tool does not rerun, or None to rerun it."""
    signals = re.search(r"#\s*(kill|INT|TERM|KILL|SIGINT|SIGTERM|SIGKILL)\b|\bkill -9\b|twice at once| & ",
                        command)
    for prefix, tests in COVERED:
        if surface.startswith(prefix):
            return tests
    if signals:
        return "tests/test_interrupt.py, tests/test_campaign_dataset.py"
    return None


# --- inputs ------------------------------------------------------------------------------

def toml_value(text: str) -> str | None:
    """The longest prefix of ``text`` that is one TOML value (the case's comment cut off)."""
    for end in range(len(text), 0, -1):
        candidate = text[:end].strip()
        if not candidate:
            break
        try:
            tomllib.loads(f"x = {candidate}")
        except tomllib.TOMLDecodeError:
            continue
        return candidate
    return None


def edit_toml(text: str, section: str | None, key: str, value: str) -> str:
    """``text`` with ``key`` of ``section`` (None: the top level; the first [[table]] of an
    array) set to ``value``, added at the section's end when absent."""
    lines, current, where = text.splitlines(), None, None
    for i, line in enumerate(lines):
        header = re.match(r"^\[+([^\]]+)\]+", line)
        if header:
            if current == section and where is None and section is not None:
                where = ("add", i)
            current = header.group(1).strip()
            if where is not None:
                break
            continue
        if current == section and re.match(rf"^{re.escape(key)}\s*=", line):
            lines[i] = f"{key} = {value}"
            return "\n".join(lines) + "\n"
    if section is None:
        return f"{key} = {value}\n" + text
    if where is None and current == section:
        return text.rstrip("\n") + f"\n{key} = {value}\n"
    if where is None:
        return text.rstrip("\n") + f"\n[{section}]\n{key} = {value}\n"
    lines.insert(where[1], f"{key} = {value}")
    return "\n".join(lines) + "\n"


def drop_section(text: str, section: str) -> str:
    out, skipping = [], False
    for line in text.splitlines():
        header = re.match(r"^\[+([^\]]+)\]+", line)
        if header:
            skipping = header.group(1).strip() == section
        if not skipping:
            out.append(line)
    return "\n".join(out) + "\n"


def preset_text(case: str, presets: Path) -> bytes | None:
    """A copy of azure-kinect.toml with the one edit ``case`` describes, or None."""
    az = (presets / "azure-kinect.toml").read_text()
    specials = {
        r"^\[illuminator\] section removed": lambda: edit_toml(drop_section(az, "illuminator"), "sensor",
                                                                "auto_exposure", "false"),
        r"wrong case key": lambda: re.sub(r"(?m)^power_w\b", "power_W", az, count=1),
        r"^duplicate key illuminator\.power_w": lambda: re.sub(r"(?m)^(power_w = .*)$", r"\1\n\1", az,
                                                               count=1),
        r"^duplicate \[illuminator\] table": lambda: az + "\n[illuminator]\npower_w = 1.0\n",
        r"^unicode name and description": lambda: edit_toml(edit_toml(az, None, "name", '"Kinéct ✓ 深度"'),
                                                            None, "description", '"Ünïcödé ✓"'),
        r"^illuminator = 5": lambda: "illuminator = 5\n" + drop_section(az, "illuminator"),
        r"^auto preset \(kinect-v2\) with \[illuminator\] and \[conditions\]": lambda: (
            (presets / "kinect-v2.toml").read_text() + "\n[illuminator]\npower_w = 1.0\nwavelength_nm = 850.0\n"
            "fov_deg = [70.0, 60.0]\noffset_m = [0.0, 0.0, 0.0]\n[conditions]\nambient_irradiance_uw_cm2_nm = 2.2\n"),
    }
    if case.startswith("UTF-8 BOM"):
        return b"\xef\xbb\xbf" + az.encode()
    if case.startswith("CRLF"):
        return az.replace("\n", "\r\n").encode()
    for pattern, make in specials.items():
        if re.search(pattern, case):
            return make().encode()
    edit = re.match(r"^(?:(\w+)(?:\[0\])?\.)?(\w+) = (.*)$", case)
    if not edit:
        return None
    value = toml_value(edit.group(3))
    if value is None:
        return None
    return edit_toml(az, edit.group(1), edit.group(2), value).encode()


def fmcw_xml(case: str, street: str) -> str | None:
    """The shipped FMCW street scene with the one edit ``case`` describes, or None."""
    def put(text, key, tag, value):
        pattern = rf'<(\w+) name="{key}" value="[^"]*"/>'
        if re.search(pattern, text):
            return re.sub(pattern, f'<{tag} name="{key}" value="{value}"/>', text, count=1)
        return text.replace('<string name="fmcw_beam"', f'<{tag} name="{key}" value="{value}"/>\n'
                            '        <string name="fmcw_beam"', 1)
    tags = {"fmcw_bins": "integer", "fmcw_beam": "string"}
    if case.startswith("the street scene as shipped"):
        return street
    if m := re.match(r"^misspelt (fmcw_\w+)", case):
        return street.replace('name="fmcw_bandwidth"', f'name="{m.group(1)}"', 1)
    if m := re.match(r"^(fmcw_\w+) given twice \((\S+) and (\S+)\)", case):
        line = f'<integer name="{m.group(1)}" value="{m.group(2)}"/>'
        return street.replace(line, line + f'<integer name="{m.group(1)}" value="{m.group(3)}"/>', 1)
    if m := re.match(r"^(fmcw_\w+) as <(\w+)> '?([^' ]+)'?", case):
        return put(street, m.group(1), m.group(2), m.group(3))
    m = re.match(r"^(fmcw_\w+) = ('[^']*'|\S+)", case)
    if not m:
        return None
    key, value = m.group(1), m.group(2).strip("'")
    text = put(street, key, tags.get(key, "float"), value)
    if "(collimated" in case:
        text = put(text, "fmcw_beam", "string", "collimated")
    return text


def dataset_toml(samples: int, seed: int, edits: dict | None = None) -> str:
    """examples/dataset.toml at 16x16, 4 spp, two samples a shard, ``edits`` (section.key:
    TOML value) applied."""
    text = (ROOT / "examples" / "dataset.toml").read_text()
    text = edit_toml(edit_toml(text, None, "samples", str(samples)), None, "seed", str(seed))
    text = edit_toml(edit_toml(text, "render", "resolution", "[16, 16]"), "render", "spp", "4")
    for dotted, value in (edits or {}).items():
        section, key = dotted.split(".")
        text = edit_toml(text, section, key, value)
    return text


def dc_config(case: str, cfg: Path, presets: Path) -> str | None:
    """A two-sample dataset config with the edit of a 'dataset config' row, or None;
    ``presets``: the packaged presets (a row naming PRnn reads the scratch copy, if made)."""
    base = dataset_toml(2, 0)
    if m := re.search(r"\((PR\d+)\)$", case):
        edit = re.search(r" with (\w+\.\w+ = \S+)", case)
        made = cfg.parent.parent / "presets" / f"{m.group(1)}.toml"
        text = preset_text(edit.group(1), presets) if edit else made.read_bytes() if made.exists() else None
        if text is None:
            return None
        (cfg / f"{m.group(1)}.toml").write_bytes(text)
        return edit_toml(base, "render", "camera", f'"{m.group(1)}.toml"')
    if case.startswith("dataset config with a UTF-8 BOM"):
        return "\ufeff" + base
    if m := re.match(r"^dataset config with (\w+)\.(\w+) given twice", case):
        return re.sub(rf"(?m)^({m.group(2)} = .*)$", r"\1\n\1", base, count=1)
    if m := re.match(r"^preset file (\S+) edited \((\w+) \S+ -> (\S+)\)", case):
        path = cfg / m.group(1)
        path.write_text(re.sub(rf"(?m)^{m.group(2)} = .*$", f"{m.group(2)} = {m.group(3)}",
                               path.read_text(), count=1))
        return ""
    m = re.match(r"^(\w+)\.(\w+) = (.*)$", case)
    value = toml_value(m.group(3)) if m else None
    if value is None:
        return None
    named = re.fullmatch(r"['\"](.+\.toml)['\"]", value)
    if named and not (cfg / named.group(1)).exists():
        shutil.copy(presets / "azure-kinect.toml", cfg / named.group(1))
    return edit_toml(base, m.group(1), m.group(2), value)


def parametric(xml: str) -> str:
    """A 16x16, 4 spp scene whose size and sample count are the parameters res and spp (the
    campaign's commands give -D res=16 -D spp=4)."""
    xml = xml.replace('<scene version="3.0.0">', '<scene version="3.0.0">\n<default name="res" value="16"/>'
                      '<default name="spp" value="4"/>', 1)
    xml = re.sub(r'(name="(?:width|height)" value=)"\d+"', r'\1"$res"', xml)
    return re.sub(r'(name="sample_count" value=)"\d+"', r'\1"$spp"', xml)


def _flip(path: Path, at: int):
    data = bytearray(path.read_bytes())
    data[at] ^= 0xFF
    path.write_bytes(bytes(data))


def _edit_json(folder: Path, edit):
    meta = json.loads((folder / "dataset.json").read_text())
    edit(meta)
    (folder / "dataset.json").write_text(json.dumps(meta, indent=1))


def _edit_h5(path: Path, edit):
    import h5py
    with h5py.File(path, "r+") as f:
        edit(f)


def _swap(d: Path):
    (d / "shard_00000.h5").rename(d / "tmp.h5")
    (d / "shard_00001.h5").rename(d / "shard_00000.h5")
    (d / "tmp.h5").rename(d / "shard_00001.h5")


def _replace(d: Path, make):
    (d / "shard_00001.h5").unlink()
    make(d / "shard_00001.h5")


def _depth_plus_one(f):
    f["sample_00000002"]["depth"][0, 0] += 1


# The shard damages of a 'dataset shards' row (``python shardcase.py ID KIND``) on a 4-sample,
# 2-shard dataset; shard 1 holds samples 2 and 3. json_layout writes the layout version after
# the reader's (the case's literal 3 was one past the reader of its day).
SHARD_DAMAGES = {
    "flip_middle": lambda d: _flip(d / "shard_00001.h5", (d / "shard_00001.h5").stat().st_size // 2),
    "truncate_half": lambda d: os.truncate(d / "shard_00001.h5", (d / "shard_00001.h5").stat().st_size // 2),
    "truncate_zero": lambda d: os.truncate(d / "shard_00001.h5", 0),
    "delete": lambda d: (d / "shard_00001.h5").unlink(),
    "swap": _swap,
    "dir_instead": lambda d: _replace(d, Path.mkdir),
    "symlink_other": lambda d: _replace(d, lambda p: p.symlink_to("shard_00000.h5")),
    "symlink_dangling": lambda d: _replace(d, lambda p: p.symlink_to("nowhere.h5")),
    "json_deleted": lambda d: (d / "dataset.json").unlink(),
    "json_drop_shard": lambda d: _edit_json(d, lambda m: m.update(
        shards=[s for s in m["shards"] if s["file"] != "shard_00001.h5"])),
    "json_units": lambda d: _edit_json(d, lambda m: m["units"].update(depth="mm")),
    "json_layout": lambda d: _edit_json(d, lambda m: m.update(layout_version=m["layout_version"] + 1)),
    "json_truncated": lambda d: os.truncate(d / "dataset.json", 100),
    "json_hash": lambda d: _edit_json(d, lambda m: m.update(config_hash="0" * 64)),
    "flip_signature": lambda d: _flip(d / "shard_00001.h5", 3),
    "junk_extra": lambda d: shutil.copy(d / "shard_00000.h5", d / "shard_00099.h5"),
    "stale_tmp": lambda d: (d / ".shard_00001.0123abcd.tmp.h5").write_bytes(b"\0" * 5000),
    "json_bom": lambda d: (d / "dataset.json").write_bytes(b"\xef\xbb\xbf" + (d / "dataset.json").read_bytes()),
    "json_samples_swap": lambda d: _edit_json(d, lambda m: [s.update(samples=[3, 2]) for s in m["shards"]
                                                            if s["file"] == "shard_00001.h5"]),
    "del_group": lambda d: _edit_h5(d / "shard_00001.h5", lambda f: f.__delitem__("sample_00000003")),
    "edit_depth": lambda d: _edit_h5(d / "shard_00001.h5", _depth_plus_one),
    "add_attr": lambda d: _edit_h5(d / "shard_00001.h5", lambda f: f["sample_00000002"].attrs.create("x", 1)),
    "mark_failed": lambda d: _edit_h5(d / "shard_00001.h5", lambda f: f.attrs.__setitem__("failed", [3])),
    "extra_group": lambda d: _edit_h5(d / "shard_00001.h5", lambda f: f.create_group("junk")),
    "samples_attr": lambda d: _edit_h5(d / "shard_00001.h5", lambda f: f.attrs.__setitem__("samples", [3, 2])),
    "shard_hash_attr": lambda d: _edit_h5(d / "shard_00001.h5",
                                          lambda f: f.attrs.__setitem__("config_hash", "0" * 64)),
}


def verify_category(rc: int | None, stdout: str, stderr: str, timed_out: bool = False) -> str:
    """The category of ``dataset verify`` on a damaged dataset: exit 1 with the damaged file
    named (its report), or as :func:`classify`."""
    if rc == 1 and "Traceback" not in stderr and re.search(r"shard_\d+\.h5|dataset\.json", stdout + stderr):
        return "clear"
    return classify(rc, stderr, timed_out)


class Scratch:
    """The scratch folder and the inputs the rows name, each built once on first use."""

    def __init__(self, folder: Path, run, log):
        self.dir, self.run, self.log = folder, run, log
        self.presets = ROOT / "src" / "dopplertof" / "cameras" / "presets"
        self.built: dict[str, str | None] = {}

    def ensure(self, token: str, row: dict) -> str | None:
        """Build the input ``token`` names (a path in the command); None when built or not an
        input, else why it cannot be."""
        for name, why in UNBUILT.items():
            if token == name or token.startswith(name.rstrip("/") + "/"):
                return why
        key = token if token.startswith(("presets/", "P/", "fx/")) else token.split("/")[0]
        if token.startswith("cfg/dc/"):  # each row's own config (a row may edit another's)
            key = f"{token}#{row['id']}"
        if key not in self.built:
            self.built[key] = self._build(key, row)
        return self.built[key]

    def _build(self, key: str, row: dict) -> str | None:
        d = self.dir
        builders = {"examples": self._examples, "az_scene.xml": self._scenes, "az_area.xml": self._scenes,
                    "az_env.xml": self._scenes, "az_point.xml": self._scenes, "cfg": self._configs,
                    "ds_big": self._datasets, "ds_ref_copy": self._datasets, "afile": self._plain,
                    "emptydir": self._plain, "emptydir_v": self._plain, "nonempty": self._plain}
        if re.fullmatch(r"az_far\d+\.xml", key):
            return self._far(key)
        if re.fullmatch(r"(presets|P)/\w+\.toml", key):
            text = preset_text(row["case"], self.presets)
            if text is None:
                return f"the case '{row['case']}' is not an edit the tool knows"
            (d / key).parent.mkdir(exist_ok=True)
            (d / key).write_bytes(text)
            return None
        if key == "presets/":
            (d / "presets").mkdir(exist_ok=True)
            return None
        if re.fullmatch(r"fx/\w+\.xml", key):
            text = fmcw_xml(row["case"], (ROOT / "examples" / "fmcw_street.xml").read_text())
            if text is None:
                return f"the case '{row['case']}' is not an edit the tool knows"
            (d / "fx").mkdir(exist_ok=True)
            (d / key).write_text(text)
            return None
        if re.fullmatch(r"cfg/dc/\w+\.toml#\w+", key):
            self.ensure("cfg", row)
            text = dc_config(row["case"], d / "cfg" / "dc", self.presets)
            if text is None:
                return f"the case '{row['case']}' is not an edit the tool knows"
            if text:
                (d / key.split("#")[0]).write_text(text)
            return None
        if key in builders:
            return builders[key](key)
        return self._captures(key)

    def _examples(self, key):
        shutil.copytree(ROOT / "examples", self.dir / "examples", dirs_exist_ok=True)

    def _scenes(self, key):
        sys.path.insert(0, str(ROOT / "src"))
        from dopplertof.cameras.accuracy import wall_scene_xml
        text = parametric(wall_scene_xml(2.0, 0.5, 75.0, 16, 4))
        lights = {"az_scene.xml": "", "az_point.xml": '<emitter type="point"><point name="position" x="0" '
                  'y="0" z="0"/><rgb name="intensity" value="10"/></emitter>',
                  "az_env.xml": '<emitter type="constant"><rgb name="radiance" value="0.5"/></emitter>',
                  "az_area.xml": '<shape type="rectangle"><transform name="to_world"><translate z="1.5"/>'
                  '<scale value="0.2"/></transform><emitter type="area"><rgb name="radiance" value="5"/>'
                  '</emitter></shape>'}
        for name, light in lights.items():
            (self.dir / name).write_text(text.replace("</scene>", light + "\n</scene>"))

    def _far(self, key):
        sys.path.insert(0, str(ROOT / "src"))
        from dopplertof.cameras.accuracy import wall_scene_xml
        distance = float(re.search(r"\d+", key).group())
        (self.dir / key).write_text(parametric(wall_scene_xml(distance, 0.9, 75.0, 16, 4)))

    def _plain(self, key):
        if key == "afile":
            (self.dir / key).write_text("a file\n")
        else:
            (self.dir / key).mkdir(exist_ok=True)
            if key == "nonempty":
                (self.dir / key / "keep.txt").write_text("keep\n")

    def _configs(self, key):
        (self.dir / "cfg" / "dc").mkdir(parents=True, exist_ok=True)
        (self.dir / "cfg" / "big.toml").write_text(dataset_toml(12, 3))
        (self.dir / "cfg" / "big_b.toml").write_text(dataset_toml(12, 4))

    def _datasets(self, key):
        self.ensure("cfg", {})
        if not (self.dir / "ds_big").exists():
            self.run("dopplertof dataset cfg/big.toml -o ds_big --workers 1 --quiet")
        if key == "ds_ref_copy":
            shutil.copytree(self.dir / "ds_big", self.dir / "ds_ref_copy")
        return None if (self.dir / key).exists() else "building it failed"

    def _captures(self, key):
        """The capture, fmcw and fit inputs; None for a name that is no input here."""
        self.ensure("examples", {})
        self.ensure("az_scene.xml", {})
        made = {"ref_dopplertof_cap_s1": "capture examples/translating_sphere.xml -D res=16 --spp 4 --seed 1",
                "ref_dopplertof_fmc_s1": "fmcw examples/fmcw_street.xml -D res=16 -D spp=4 --bins 128 --seed 1",
                "capdir_o": "capture examples/fmcw_street.xml -D res=16 -D spp=4",
                "fitcap": "capture examples/translating_sphere.xml -D res=16 --spp 4",
                "fitak": "capture az_scene.xml --camera azure-kinect --res 16x16 --spp 4",
                "fitcam": "capture examples/translating_sphere.xml --camera paper-dtof --res 16x16 --spp 4"}
        base = re.sub(r"(_[tchn]|2)$", "", key)
        if key not in made and base != "fitcap":
            return None
        if not (self.dir / base).exists():
            quiet = " --quiet" if made[base].startswith("capture") else ""
            self.run(f"dopplertof {made[base]}{quiet} -o {base}")
        if not (self.dir / base).exists():
            return f"building {base} failed"
        if key != base:
            shutil.copytree(self.dir / base, self.dir / key)
            return self._damage_capture(key)
        return None

    def _damage_capture(self, key):
        import numpy as np
        folder = self.dir / key
        if key.endswith("_t"):
            data = (folder / "summary.json").read_bytes()[:50]
            (folder / "summary.json").write_bytes(data)
        elif key.endswith("_c"):
            (folder / "camera.json").unlink(missing_ok=True)
        elif key.endswith(("_h", "_n")):
            target = folder / "heterodyne_0.npy"
            if not target.exists():
                return "the capture has no heterodyne_0.npy to replace"
            a = np.load(target)
            np.save(target, np.zeros((8, 8, 3), a.dtype) if key.endswith("_h") else np.full_like(a, np.nan))
        return None


API_PRELUDE = r'''
import pathlib, sys, tempfile
import numpy as np
import dopplertof, mitsuba as mi
dopplertof.set_variant()
from dopplertof.fmcw import Chirp, fmcw
from dopplertof.cameras import load_preset, capture_camera
from dopplertof.dataset import Dataset
from dopplertof.dataset.export import export_dataset
from dopplertof.dataset.driver import verify_dataset
expr, AZURE = sys.argv[1], sys.argv[2]
scene = dopplertof.load_file("examples/fmcw_street.xml", {"res": "8", "spp": "2"})
if "sphere" in expr or "CameraResult" in expr:
    from dopplertof.cameras.accuracy import wall_scene_xml
    from dopplertof.cameras.capture import with_illuminator
    from dopplertof.cameras.radiometry import view_tangents
    from dopplertof.scene import load_string
    az = load_preset("azure-kinect")
    sphere = load_string(with_illuminator(wall_scene_xml(2.0, 0.5, az.fov_deg, 8, 4), az,
                                          view_tangents(az.fov_deg, 8, 8)), {}, source="wall")
if "CameraResult" in expr:
    CameraResult, folder = capture_camera(sphere, az, 4, 0, progress=False), tempfile.mkdtemp()
if "FMCWResult" in expr:
    FMCWResult = fmcw(scene, spp=2)
try:
    value = eval(expr)
except Exception as e:
    ours = type(e).__module__.startswith("dopplertof") or isinstance(e, (TypeError, ValueError))
    if not ours:
        raise
    message = " ".join(str(e).split())
    print(f"{type(e).__name__}: {message}", file=sys.stderr)
    sys.exit(2 if message else 1)
print(repr(value)[:200])
'''
# The words of a Python API row's case that stand for an expression: what they stand for.
API_WORDS = (("fmcw(plain mitsuba scene, mi.load_dict(cornell_box))", "fmcw(mi.load_dict(mi.cornell_box()))"),
             ("pathlib.Path(azure-kinect.toml)", "pathlib.Path(AZURE)"),
             ("(..., ", "(sphere, 'azure-kinect', spp=4, "))


def api_expression(case: str) -> str | None:
    """The Python expression of an API row (its trailing comment cut off), or None."""
    for words, expression in API_WORDS:
        case = case.replace(words, expression)
    for end in range(len(case), 0, -1):
        try:
            compile(case[:end], "<row>", "eval")
        except SyntaxError:
            continue
        return case[:end].strip()
    return None


def run_command(argv: list[str], cwd: Path, env: dict, timeout: float):
    """(rc, stdout, stderr, timed out) of ``argv`` in its own process group."""
    p = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, errors="replace", start_new_session=True)
    try:
        out, err = p.communicate(timeout=timeout)
        return p.returncode, out, err, False
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        out, err = p.communicate()
        return p.returncode, out, err, True


def steps_of(command: str) -> list[str]:
    if command.startswith("bash -c "):
        return [command]
    return [step.strip() for step in command.split(" ; ")]


def tokens_of(step: str) -> list[str]:
    import shlex
    try:
        words = shlex.split(step)
    except ValueError:
        return []
    if words[:2] == ["bash", "-c"] and len(words) > 2:
        return tokens_of(words[2])
    return [w for w in words if not w.startswith("-")]


class Rerun:
    def __init__(self, scratch: Path, timeout: float, log=print):
        self.dir, self.timeout, self.log = scratch, timeout, log
        bin_dir = scratch / "bin"
        bin_dir.mkdir(parents=True, exist_ok=True)
        wrapper = bin_dir / "dopplertof"
        wrapper.write_text(f'#!/bin/sh\nexec {sys.executable} -c "{CLI}" "$@"\n')
        wrapper.chmod(0o755)
        (scratch / "api_row.py").write_text(API_PRELUDE)
        self.env = dict(os.environ, PYTHONPATH=str(ROOT / "src"),
                        PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}")
        self.inputs = Scratch(scratch, self._setup, log)

    def _setup(self, command: str):
        rc, _, err, _ = run_command(["bash", "-c", command], self.dir, self.env, self.timeout)
        if rc:
            self.log(f"  input '{command}' failed ({rc}): {err.strip()[-300:]}")

    def row(self, row: dict) -> dict:
        command = row["command"]
        tests = covered_by(row["surface"], command)
        if tests:
            return {"status": "covered", "by": tests}
        shard = re.fullmatch(r"python shardcase\.py (\w+) (\w+)", command)
        if shard:
            return self._shard_row(*shard.groups())
        if command.startswith("python: "):
            expression = api_expression(row["case"])
            if expression is None:
                return {"status": "not rebuilt", "why": "the case is not a Python expression"}
            for token in ("examples", "az_scene.xml", *re.findall(r"'(ds_\w+)'", expression)):
                why = self.inputs.ensure(token, row)
                if why:
                    return {"status": "not rebuilt", "why": f"{token}: {why}"}
            argvs = [[sys.executable, "api_row.py", expression,
                      str(self.inputs.presets / "azure-kinect.toml")]]
            return self._run(argvs, None)  # an API error describes its argument by its role
        else:
            steps = steps_of(command)
            for token in (t for step in steps for t in tokens_of(step)):
                why = self.inputs.ensure(token, row)
                if why:
                    return {"status": "not rebuilt", "why": f"{token}: {why}"}
            argvs = [["bash", "-c", step] for step in steps]
        return self._run(argvs, row_names(command, row["case"]))

    def _shard_row(self, rid: str, kind: str) -> dict:
        """The damage ``kind`` on a copy of a 4-sample dataset, then ``dataset verify``."""
        if kind not in SHARD_DAMAGES:
            return {"status": "not rebuilt", "why": f"the damage '{kind}' needs shardcase.py, not in the TSV "
                    "(tests/test_dataset.py's DAMAGES hold ten kinds of shard damage)"}
        four = self.dir / "ds_four"
        if not four.exists():
            self.inputs.ensure("cfg", {})
            (self.dir / "cfg" / "four.toml").write_text(dataset_toml(4, 3))
            self._setup("dopplertof dataset cfg/four.toml -o ds_four --workers 1 --quiet")
        if not (four / "dataset.json").exists():
            return {"status": "not rebuilt", "why": "building the 4-sample dataset failed"}
        folder = self.dir / f"dmg_{rid}"
        shutil.rmtree(folder, ignore_errors=True)
        shutil.copytree(four, folder, symlinks=True)
        SHARD_DAMAGES[kind](folder)
        start = time.monotonic()
        rc, out, err, timed_out = run_command(["dopplertof", "dataset", "verify", folder.name], self.dir,
                                              self.env, self.timeout)
        lines = [line for line in (out + err).splitlines() if line.strip()]
        return {"status": "rerun", "now": verify_category(rc, out, err, timed_out), "rc": rc,
                "stderr": lines[-3:], "seconds": round(time.monotonic() - start, 1)}

    def _run(self, argvs, names) -> dict:
        start = time.monotonic()
        for argv in argvs:
            rc, out, err, timed_out = run_command(argv, self.dir, self.env, self.timeout)
            now = classify(rc, err, timed_out, names)
            if now != "ok":
                break
        lines = [line for line in err.splitlines() if line.strip()]
        return {"status": "rerun", "now": now, "rc": rc, "stderr": lines[-3:],
                "seconds": round(time.monotonic() - start, 1)}


def read_rows(tsv: Path) -> list[dict]:
    lines = tsv.read_text(encoding="utf-8").splitlines()
    head = lines[0].split("\t")
    return [dict(zip(head, line.split("\t"))) for line in lines[1:] if line.strip()]


def summarise(rows: list[dict], results: dict, reviewed: dict | None = None) -> dict:
    """Counts before and now, and the rows each verdict names; a regression whose row
    ``reviewed`` explains (id: why the change is meant) is 'reviewed' instead."""
    before = Counter(r["category"] for r in rows)
    now, verdicts = Counter(), {}
    for r in rows:
        res = results[r["id"]]
        if res["status"] == "rerun":
            now[res["now"]] += 1
            res["verdict"] = verdict(r["category"], res["now"])
            if res["verdict"] == "regression" and r["id"] in (reviewed or {}):
                res["verdict"], res["reviewed"] = "reviewed", reviewed[r["id"]]
            verdicts.setdefault(res["verdict"], []).append(r["id"])
        else:
            now[res["status"]] += 1
    by_recorded = {}
    for r in rows:
        res = results[r["id"]]
        key = res.get("now", res["status"])
        by_recorded.setdefault(r["category"], Counter())[key] += 1
    return {"rows": len(rows), "before": dict(before), "now": dict(now),
            "recorded_vs_now": {k: dict(v) for k, v in by_recorded.items()},
            "verdicts": verdicts}


def print_summary(summary: dict, rows: list[dict], results: dict):
    kinds = list(CATEGORIES) + ["covered", "not rebuilt"]
    print(f"\n{'recorded':<14}{'rows':>6}  " + "".join(f"{k:>12}" for k in kinds))
    for cat in RECORDED:
        counts = summary["recorded_vs_now"].get(cat, {})
        print(f"{cat:<14}{summary['before'].get(cat, 0):>6}  " + "".join(f"{counts.get(k, 0):>12}" for k in kinds))
    print(f"{'now':<14}{summary['rows']:>6}  " + "".join(f"{summary['now'].get(k, 0):>12}" for k in kinds))
    for name in ("regression", "reviewed", "wording", "changed"):
        for rid in summary["verdicts"].get(name, []):
            res = results[rid]
            row = next(r for r in rows if r["id"] == rid)
            print(f"{name}: {rid} was {row['category']}, now {res['now']} (rc {res['rc']}): "
                  f"{' | '.join(res['stderr'])[:300]}" + (f"\n    reviewed: {res['reviewed']}" if
                                                            name == "reviewed" else ""))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("tsv", type=Path)
    parser.add_argument("--scratch", type=Path, required=True, help="an empty or new folder")
    parser.add_argument("-o", "--output", type=Path, default=Path("campaign_rerun.json"))
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds per command")
    parser.add_argument("--reviewed", type=Path, help="a TSV of id and why the row's change is meant")
    parser.add_argument("--only", default="", help="a regular expression on the row ids")
    args = parser.parse_args(argv)
    rows = [r for r in read_rows(args.tsv) if re.match(args.only, r["id"])]
    args.scratch.mkdir(parents=True, exist_ok=True)
    rerun, results = Rerun(args.scratch.resolve(), args.timeout), {}
    for r in rows:
        try:
            results[r["id"]] = res = rerun.row(r)
        except Exception as e:  # the tool's own failure on one row: said, and the rest go on
            results[r["id"]] = res = {"status": "not rebuilt", "why": f"the tool failed: {e!r}"}
        print(f"{r['id']:<7}{r['category']:<14}{res.get('now', res['status']):<12}"
              f"{(res.get('stderr') or [''])[-1][:110] if res['status'] == 'rerun' else res.get('why', res.get('by', ''))[:110]}",
              flush=True)
    reviewed = {}
    if args.reviewed:
        for line in args.reviewed.read_text(encoding="utf-8").splitlines():
            if line.strip() and not line.startswith("#"):
                rid, why = line.split("\t", 1)
                reviewed[rid] = why
    summary = summarise(rows, results, reviewed)
    print_summary(summary, rows, results)
    args.output.write_text(json.dumps({"tsv": str(args.tsv), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                                       "summary": summary, "results": results}, indent=1))
    print(f"wrote {args.output}")
    return 1 if summary["verdicts"].get("regression") else 0


if __name__ == "__main__":
    sys.exit(main())
