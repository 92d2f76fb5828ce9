"""tools/check_doc_numbers.py (issue 42, 2026-12-03): the docs' quoted figures it lists are
still quoted in their docs (a Python call's named command too), and it re-measures four cheap
ones within 10% (two `dopplertof` commands and two calls of benchmarks/camera_accuracy.py's
function) and flags a figure that drifted."""

import pytest

from conftest import load_script


def tool():
    return load_script("tools/check_doc_numbers.py")


def test_every_registered_figure_is_quoted_in_its_doc():
    check = tool()
    names = [entry[0] for entry in check.REGISTRY]
    assert len(names) == len(set(names))
    for name, doc, text, quoted, command, _, _ in check.REGISTRY:
        assert check.quoted_in(doc, text, command), (name, doc, text, str(command))
        # the command is the doc's own (its scene, options), with {out} for the folder; a
        # call names the script the doc names
        assert isinstance(command, check.Call) and command.named or "{out}" in command
    # a quoted 0 (no pixel failing to unwrap) holds only where none is measured
    assert check.drift_of(0, 0) == 0 and check.drift_of(0, 1) > check.TOLERANCE


def test_four_cheap_figures_re_measure_and_a_drift_is_flagged():
    import dopplertof

    dopplertof.set_variant()
    check = tool()
    chosen = [e for e in check.REGISTRY
              if e[0] in ("sphere-ball-median", "tumble-torus-median", "azure-kinect-random",
                          "readme-azure-kinect-wfov-unbinned-random")]
    name, doc, text, quoted, command, read, cheap = chosen[0]
    drifted = (name + "-doubled", doc, text, 2 * quoted, command, read, cheap)
    rows = {row[0]: row for row in check.check(chosen + [drifted])}
    assert rows["sphere-ball-median"][5] == "ok"
    assert rows["tumble-torus-median"][5] == "ok"
    assert rows["azure-kinect-random"][5] == "ok"
    # the README quoted 28 mm (2026-12-03) for what its command measures as 20.0 mm
    assert rows["readme-azure-kinect-wfov-unbinned-random"][5] == "ok"
    assert rows["sphere-ball-median-doubled"][5] == "DRIFT"
    assert rows["sphere-ball-median-doubled"][4] == pytest.approx(0.5, abs=0.05)
