"""The docs' code blocks (README.md and docs/*.md), read as a user copies them (issue 42)."""

import glob
import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOCS = [os.path.join(ROOT, "README.md")] + sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))
_FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.S | re.M)

#: calls that need a Mitsuba variant set (dopplertof.set_variant()) before them
NEEDS_VARIANT = re.compile(r"\b(load_file|load_string|load_scene_for_camera|capture_camera|"
                           r"dopplertof\.capture|dopplertof\.render|DifferentiableScene|"
                           r"\.scene)\(")


def blocks(language: str):
    """(doc's name, line, text) of every fenced block of ``language`` in the docs."""
    out = []
    for path in DOCS:
        text = open(path, encoding="utf-8").read()
        for m in _FENCE.finditer(text):
            if m.group(1) == language:
                line = text.count("\n", 0, m.start()) + 1
                out.append((os.path.relpath(path, ROOT), line, m.group(2)))
    return out


def _sessions():
    """Each doc's Python blocks as one session each (a user runs a doc's blocks in
    order: a later block continues the earlier ones), with the doc's name."""
    out = {}
    for doc, line, code in blocks("python"):
        out.setdefault(doc, []).append((line, code))
    return sorted(out.items())


@pytest.mark.parametrize("doc, parts", _sessions(), ids=[d for d, _ in _sessions()])
def test_a_python_block_that_loads_a_scene_sets_the_variant_first(doc, parts):
    """A doc's Python that loads a scene (or renders) calls dopplertof.set_variant()
    before: without it the first call raises (issue 42: docs/cameras.md's
    capture_camera, docs/dataset.md's ds.scene(0))."""
    code = "".join(text for _, text in parts)
    need = NEEDS_VARIANT.search(code)
    if need is None:
        return
    first = code.find("set_variant(")
    assert 0 <= first < need.start(), f"{doc}: {need.group(0)} before set_variant()"


# ---- Every Python and shell block, run ----------------------------------------------

#: the line before a block that is not run, with the reason: ``<!-- not run by
#: tests/test_docs.py: REASON -->``
_NOT_RUN = re.compile(r"<!-- not run by tests/test_docs\.py: (.*?) -->\s*$")

#: the sizes a block runs at: its numbers made tiny (rule, replacement), shell then Python
SH_TINY = [(r"^\.venv/bin/", ""), (r"(?<=\s)\.venv/bin/", ""), (r"(?<=\s)/tmp/", ""), (r"--spp \d+", "--spp 8"),
           (r"--reference-spp \d+", "--reference-spp 16"), (r"--frames \d+", "--frames 2"),
           (r"--res \d+x\d+", "--res 16x13"), (r"-D res=\d+", "-D res=16"),
           (r"--workers \d+", "--workers 1")]
PY_TINY = [(r"\bspp=\d+", "spp=8"), (r"resolution=\(\d+, \d+\)", "resolution=(16, 13)"),
           (r'"res": \d+', '"res": 16'), (r"workers=\d+", "workers=1"),
           (r'(run_animation\("[^"]+", "[^"]+", )\d+', r"\g<1>2"),
           (r'write_figures\("figs/"\)', 'write_figures("figs/", quick=True)')]
#: options a command gets when it has none of its own (its size)
SH_ADDED = [(r"^dopplertof demo\b", "--res", "--res 32 --spp 16"),
            (r"^dopplertof fit\b", "--spp", "--spp 8"),
            (r"^dopplertof fit\b", "--iterations", "--iterations 1"),
            (r"^dopplertof capture\b.*--camera", "--res", "--res 16x13"),
            (r"^dopplertof (capture|render|precision|animate)\b", "-D res=", "-D res=16"),
            (r"^dopplertof sweep --preset", "--quick", "--quick -D res=16"),
            (r"^dopplertof figures\b", "--quick", "--quick")]


def runnable_blocks(doc: str):
    """(kind, line, code at the tiny sizes) of the doc's Python and shell blocks in
    order, and (line, reason) of those marked not to run."""
    text = open(os.path.join(ROOT, doc), encoding="utf-8").read()
    run, skipped = [], []
    for m in _FENCE.finditer(text):
        if m.group(1) not in ("python", "sh"):
            continue
        line = text.count("\n", 0, m.start()) + 1
        before = text[:m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        marked = _NOT_RUN.search(before)
        if marked:
            skipped.append((line, marked.group(1)))
        else:
            run.append((m.group(1), line, tiny(m.group(1), m.group(2))))
    return run, skipped


def tiny(kind: str, code: str) -> str:
    """``code`` at the sizes of the test (:data:`SH_TINY`, :data:`PY_TINY`,
    :data:`SH_ADDED`)."""
    if kind == "python":
        for rule, replacement in PY_TINY:
            code = re.sub(rule, replacement, code)
        return code
    lines = []
    for line in code.splitlines():
        command, _, comment = line.partition("  #")
        for rule, replacement in SH_TINY:
            command = re.sub(rule, replacement, command.strip())
        for rule, present, added in SH_ADDED:
            if re.search(rule, command) and present not in command:
                command += " " + added
        lines.append(command)
    return "\n".join(lines) + "\n"


def _scratch(folder) -> None:
    """The files the docs' blocks name, in ``folder``: ``examples/`` and ``src/`` of the
    repository (linked), ``scene.xml`` (the demo's Cornell box at 24x24), ``sweep.toml``
    (examples/sweep_tiny.toml) and ``path/to/mine.toml`` (a packaged camera preset)."""
    import shutil

    for name in ("examples", "src"):
        os.symlink(os.path.join(ROOT, name), os.path.join(folder, name))
    demo = os.path.join(ROOT, "src", "dopplertof", "data", "cornell_demo.xml")
    with open(demo, encoding="utf-8") as f:
        scene = f.read().replace('<default name="res" value="128"/>',
                                 '<default name="res" value="24"/>')
    with open(os.path.join(folder, "scene.xml"), "w", encoding="utf-8") as f:
        f.write(scene)
    with open(os.path.join(ROOT, "examples", "sweep_tiny.toml"), encoding="utf-8") as f:
        sweep = f.read().replace('"../src/dopplertof/data/cornell_demo.xml"', repr(demo))
    with open(os.path.join(folder, "sweep.toml"), "w", encoding="utf-8") as f:
        f.write(sweep)
    os.makedirs(os.path.join(folder, "path", "to"))
    shutil.copy(os.path.join(ROOT, "src", "dopplertof", "cameras", "presets", "paper-dtof.toml"),
                os.path.join(folder, "path", "to", "mine.toml"))


_DRIVER = '''import json, subprocess, sys

if __name__ == "__main__":   # (worker processes that import this file run nothing)
    namespace = {"__name__": "__main__"}
    for kind, line, code in json.load(open(sys.argv[1])):
        print(f"--- {kind} block at line {line}", flush=True)
        if kind == "sh":
            subprocess.run(["bash", "-e", "-c", code], check=True)
        else:
            exec(compile(code, f"block at line {line}", "exec"), namespace)
'''


@pytest.mark.slow  # every doc's blocks at tiny sizes (a minute or two for the README)
@pytest.mark.parametrize("doc", [os.path.relpath(p, ROOT) for p in DOCS])
def test_every_python_and_shell_block_runs(doc, tmp_path):
    """issue 42: the docs' blocks did not run as written (an ImportError, a missing
    set_variant, placeholders). Each doc's blocks run in order in a scratch folder, the
    Python ones in one namespace, at tiny sizes; a block that cannot run is marked in
    the doc, with its reason."""
    import json
    import subprocess
    import sys

    blocks, skipped = runnable_blocks(doc)
    assert all(reason.strip() for _, reason in skipped), skipped
    if not blocks:
        return
    _scratch(str(tmp_path))
    (tmp_path / "blocks.json").write_text(json.dumps(blocks))
    (tmp_path / "driver.py").write_text(_DRIVER)
    env = dict(os.environ, MPLBACKEND="Agg",
               PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"])
    done = subprocess.run([sys.executable, "driver.py", "blocks.json"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=900, env=env)
    assert done.returncode == 0, f"{doc}:\n{done.stdout[-3000:]}\n{done.stderr[-5000:]}"


# ---- Every shell command in a block the runner sees ----------------------------------

#: a command line as the docs write one: `dopplertof ...`, `python ...`, `make ...`, after an
#: optional prompt, `cd DIR && `, `nice -n N `, an environment variable and a folder
_COMMAND = re.compile(r"^(\$ )?(cd \S+ && )?(nice -n \d+ )?(\w+=\S+ )?(\S*/)?"
                      r"(dopplertof|python3?|make)( +\S|$)")


def commands_outside_blocks(text: str) -> list:
    """(line, text) of the command lines in ``text`` that tests/test_docs.py never sees:
    in a fenced block of another language than python or sh (none, bash, console), or
    indented (an indented code block, or a line a paragraph carries on)."""
    handled, fenced = set(), set()
    for m in _FENCE.finditer(text):
        first, last = text.count("\n", 0, m.start()), text.count("\n", 0, m.end())
        fenced.update(range(first, last + 1))
        if m.group(1) in ("python", "sh"):
            handled.update(range(first, last + 1))
    found = []
    for number, line in enumerate(text.split("\n")):
        if number in handled:
            continue
        if (number in fenced or line.startswith("    ")) and _COMMAND.match(line.strip()):
            found.append((number + 1, line.strip()))
    return found


def test_every_shell_command_is_in_a_fenced_block():
    """issue 42 (2026-12-04): about 40 command lines of the docs were indented or in a
    block of no language, so the runner above never ran them nor saw them marked. Each is
    in a fenced sh block now (run at tiny sizes, or marked with its reason)."""
    outside = {}
    for path in DOCS:
        with open(path, encoding="utf-8") as f:
            found = commands_outside_blocks(f.read())
        if found:
            outside[os.path.relpath(path, ROOT)] = found
    assert not outside, outside


def test_a_command_outside_a_fenced_block_is_found():
    text = ("Run\n\n    .venv/bin/python benchmarks/film.py\n\nor\n\n```\ndopplertof demo\n```\n"
            "```bash\n$ make quick\n```\n```sh\ndopplertof demo -o out\n```\n"
            "dopplertof on LLVM, prose that starts with the name\n"
            "    cd benchmarks && PYTHONPATH=../src ../.venv/bin/python spinning_torus.py\n")
    assert commands_outside_blocks(text) == [
        (3, ".venv/bin/python benchmarks/film.py"), (8, "dopplertof demo"),
        (11, "$ make quick"),
        (17, "cd benchmarks && PYTHONPATH=../src ../.venv/bin/python spinning_torus.py")]


def test_every_dopplertof_command_is_on_one_line():
    """A command continued with a backslash gets the test's tiny options (SH_ADDED)
    after the backslash, and a reader copies half of it: each dopplertof command in a
    fenced sh block is one line (docs/cameras.md's --compare was three)."""
    continued = [(doc, line) for doc, line, code in blocks("sh")
                 for command in code.splitlines()
                 if re.search(r"(^|/)dopplertof\b", command) and command.rstrip().endswith("\\")]
    assert not continued, continued


def test_a_doc_that_uses_pytorch_shows_its_cpu_wheel():
    """A plain ``pip install torch`` pulls the ~5 GB CUDA build: a doc whose code imports
    torch shows the CPU wheel's index beside it."""
    for path in DOCS:
        text = open(path, encoding="utf-8").read()
        if re.search(r"^import torch\b", text, re.M):
            assert "--index-url https://download.pytorch.org/whl/cpu" in text, path


def test_the_image_hash_table_lists_every_hash_the_tool_records():
    """docs/testing.md's table of tools/image_hashes.py's hashes names each hash the tool
    computes (image_hashes.names()) once, and no other."""
    import sys

    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import image_hashes

    with open(os.path.join(ROOT, "docs", "testing.md"), encoding="utf-8") as f:
        table = f.read().split("| hash | what is rendered |\n")[1].split("\n\n")[0]
    listed = [name for row in table.split("\n")[1:]
              for name in re.findall(r"`([^`]+)`", row.split(" | ")[0])]
    assert sorted(listed) == sorted(image_hashes.names())
