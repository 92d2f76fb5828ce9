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
