"""tools/campaign_status.py: the rows of a campaign that docs/reliability.md does not cite,
whichever header the campaign's TSV has (``verdict``/``what was done``, or the later
``category``/``case`` with good rows called ``clear``)."""

from conftest import load_script

OLD_HEADER = "id\tsurface\twhat was done\texpected\tobserved\tverdict\n"
NEW_HEADER = "id\tsurface\tcase\tcommand\texpected\tobserved\tcategory\n"


def _write(tmp_path, name, header, rows, doc):
    tsv = tmp_path / name
    tsv.write_text(header + "".join("\t".join(r) + "\n" for r in rows), encoding="utf-8")
    md = tmp_path / "reliability.md"
    md.write_text(doc, encoding="utf-8")
    return str(tsv), str(md)


def test_the_new_header_and_its_clear_verdict_are_read(tmp_path):
    tool = load_script("tools/campaign_status.py")
    rows = [("A01", "s", "did a", "cmd", "e", "o", "ok"),
            ("A02", "s", "did b", "cmd", "e", "o", "clear"),
            ("A03", "s", "did c", "cmd", "e", "o", "unclear"),
            ("A04", "s", "did d", "cmd", "e", "o", "silent wrong"),
            ("A05", "s", "did e", "cmd", "e", "o", "data loss")]
    doc = "# R\n\n## Campaign 2026-12-07\n\n| A03 | x | y |\n"
    tsv, md = _write(tmp_path, "campaign-2026-12-07.tsv", NEW_HEADER, rows, doc)
    listed = tool.status(tsv, md)
    assert [(r[0], r[1], r[3]) for r in listed] == [("A04", "silent wrong", "did d"),
                                                   ("A05", "data loss", "did e")]
    assert tool.main([tsv, "--doc", md]) == 1
    every = [r[0] for r in tool.status(tsv, md, every=True)]
    assert every == ["A02", "A03", "A04", "A05"]


def test_the_old_header_is_still_read(tmp_path):
    tool = load_script("tools/campaign_status.py")
    rows = [("S01", "s", "did a", "e", "o", "clear error"),
            ("S02", "s", "did b", "e", "o", "silent wrong")]
    tsv, md = _write(tmp_path, "campaign-2026-12-03.tsv", OLD_HEADER, rows,
                     "the 2026-12-03 campaign S02 is fixed\n")
    assert tool.status(tsv, md) == []
    assert tool.main([tsv, "--doc", md]) == 0


def test_a_table_row_citing_several_ids_and_a_range_cites_each(tmp_path):
    tool = load_script("tools/campaign_status.py")
    rows = [(f"B0{k}", "s", f"did {k}", "cmd", "e", "o", "unclear") for k in range(1, 7)]
    doc = ("# R\n\n## Campaign 2026-12-07\n\n| ID | what | now |\n|---|---|---|\n"
           "| B01, B02 | x | y |\n| B04-B05 | x | y |\n")
    tsv, md = _write(tmp_path, "campaign-2026-12-07.tsv", NEW_HEADER, rows, doc)
    assert [r[0] for r in tool.status(tsv, md)] == ["B03", "B06"]
