"""write_figures: every file, atomically, with the promised contents."""

import csv
import json
import math
import pathlib

import pytest

import dopplertof.analysis as analysis
from dopplertof.analysis import CSV_COLUMNS, DATA_FILES, FIGURE_FILES, METHODS, write_figures
from dopplertof.io import manifest_name

ANALYSIS_DIR = pathlib.Path(analysis.__file__).parent


@pytest.fixture(scope="module")
def quick_outputs(tmp_path_factory):
    outdir = tmp_path_factory.mktemp("figures") / "nested"   # a folder that does not exist yet
    return outdir, write_figures(outdir, quick=True)


@pytest.mark.slow
def test_every_expected_file_is_written(quick_outputs):
    outdir, written = quick_outputs
    assert [p.name for p in written] == list(FIGURE_FILES) + list(DATA_FILES)
    for path in written:
        assert path.parent == outdir and path.is_file() and path.stat().st_size > 0
    for name in FIGURE_FILES:
        assert (outdir / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in outdir.iterdir()) == sorted(
        FIGURE_FILES + DATA_FILES + (manifest_name("figures"),))


@pytest.mark.slow
def test_closed_forms_csv(quick_outputs):
    outdir, _ = quick_outputs
    with open(outdir / "closed_forms.csv", newline="") as stream:
        reader = csv.DictReader(stream)
        assert tuple(reader.fieldnames) == CSV_COLUMNS == ("omega", "method", "closed_form",
                                                          "numeric")
        rows = list(reader)
    assert {row["method"] for row in rows} == set(METHODS) == {
        "uniform", "stratified", "antithetic", "antithetic_mirror"}
    for row in rows:
        omega, closed, numeric = (float(row[k]) for k in ("omega", "closed_form", "numeric"))
        assert 0.0 < omega <= 4 * math.pi * (1 + 1e-15)
        assert abs(closed - numeric) <= 1e-11 + 1e-9 * abs(numeric)
    per_method = {m: sum(row["method"] == m for row in rows) for m in METHODS}
    assert len(set(per_method.values())) == 1 and per_method["uniform"] >= 8


@pytest.mark.slow
def test_rates_json_has_the_fitted_slopes(quick_outputs):
    outdir, _ = quick_outputs
    rates = json.loads((outdir / "rates.json").read_text())
    slopes = rates["slopes"]
    assert set(slopes) == {"uniform", "periodic", "stratified"}
    assert slopes["uniform"] == pytest.approx(-1.0, abs=1e-9)
    assert slopes["periodic"] == pytest.approx(-2.0, abs=0.15)
    assert slopes["stratified"] == pytest.approx(-3.0, abs=0.15)
    assert rates["expected_slopes"] == {"uniform": -1.0, "periodic": -2.0, "stratified": -3.0}


@pytest.mark.slow
def test_rewrite_replaces_files_and_leaves_no_temporaries(quick_outputs):
    outdir, _ = quick_outputs
    (outdir / "closed_forms.csv").write_text("stale")
    write_figures(outdir, quick=True)
    assert (outdir / "closed_forms.csv").read_text().startswith(",".join(CSV_COLUMNS))
    assert not [p for p in outdir.iterdir()
                if p.name.startswith(".") and p.name != manifest_name("figures")]


def test_analysis_never_imports_the_renderer_stack():
    for source in ANALYSIS_DIR.glob("*.py"):
        text = source.read_text()
        for module in ("mitsuba", "drjit", "matplotlib.pyplot"):
            assert f"import {module}" not in text and f"from {module}" not in text, source
