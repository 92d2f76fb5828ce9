"""Which rows of a fault campaign docs/reliability.md does not cite yet (issue 39, 2026-12-03).

A campaign is a TSV file, one case a line: id, surface, what was done, expected, observed,
verdict (campaign-2026-12-03.tsv's header; later campaigns call the columns case and
category, and a good row's verdict ``clear``: both are read). A row counts as cited when its id appears in a line of docs/reliability.md that
names the campaign ("2026-12-03 campaign S01-S09, S12"), alone or inside a range (S01-S09,
"P1-19 to P1-21"), or opens a table row under a heading naming the campaign and its date
("## Campaign rerun (issue 39, 2026-12-03)"). The rows listed are those whose verdict is none of ``ok``, ``clear error``
and ``clear``, and whose id no such line cites; ``--all`` lists every row that is not ok, cited or
not, with the docs line's first words.

    python tools/campaign_status.py ../shared/reliability/campaign-2026-12-03.tsv
"""

import argparse
import csv
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GOOD = ("ok", "clear error", "clear")
#: the columns read, each under the names campaigns give it
COLUMNS = {"verdict": ("verdict", "category"), "what was done": ("what was done", "case")}
#: an id (S01, P05c, D28bad, P1-19), then maybe a range's end ("-S09", " to P1-21")
_ID = r"[A-Z]+\d*-\d+|[A-Z]+\d+[a-z]*"
_CITE = re.compile(rf"\b({_ID})\b(?:\s*(?:-|to)\s*\b({_ID})\b)?")


def read_campaign(path: str) -> list:
    """The campaign's rows as dicts keyed by the header's columns, with ``verdict`` and
    ``what was done`` under those names whatever the header calls them (COLUMNS)."""
    with open(path, encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f, delimiter="\t"))
    for row in rows:
        for key, names in COLUMNS.items():
            row.setdefault(key, next((row[n] for n in names if row.get(n) is not None), ""))
    return rows


def _split(case_id: str):
    """(prefix, number, suffix) of an id: P1-19 -> ('P1-', 19, ''), P05c -> ('P', 5, 'c')."""
    m = re.fullmatch(r"(.*?)(\d+)([a-z]*)", case_id)
    return m.group(1), int(m.group(2)), m.group(3)


def cited_ids(doc_text: str, ids: list, campaign: str) -> dict:
    """{id: the docs line citing it} for the ids of ``ids`` that a line naming
    ``campaign`` (its date) cites, or that the first cell of a table row under a
    heading naming the campaign lists ("| PR30, PR31 |"), ranges expanded over ``ids``."""
    known, out, rerun = set(ids), {}, False
    for line in doc_text.splitlines():
        if line.startswith("#"):  # a rerun's section: its table's rows cite their ids
            rerun = campaign in line and "campaign" in line.lower()
        cells = (line.split("|")[1] if rerun and line.startswith("|") else "",
                 line if f"{campaign} campaign" in line else "")
        for text in cells:
            for first, last in _CITE.findall(text):
                for i in _expanded(first, last, ids, known):
                    out.setdefault(i, line)
    return out


def _expanded(first: str, last: str, ids: list, known: set) -> list:
    """The ids a citation names: ``first``, or the range ``first`` to ``last``."""
    if first not in known:
        return []
    if last not in known:
        return [first]
    (p, lo, _), (q, hi, _) = _split(first), _split(last)
    if p != q:
        return [first, last]
    return [i for i in ids if _split(i)[0] == p and lo <= _split(i)[1] <= hi]


def status(tsv: str, doc: str, every: bool = False) -> list:
    """(id, verdict, cited line or '', what was done) of the rows to list."""
    rows = read_campaign(tsv)
    date = re.search(r"\d{4}-\d{2}-\d{2}", os.path.basename(tsv))
    with open(doc, encoding="utf-8") as f:
        cited = cited_ids(f.read(), [r["id"] for r in rows], date.group(0) if date else "")
    out = []
    for r in rows:
        bad = r["verdict"] not in GOOD
        if (every and r["verdict"] != "ok") or (bad and r["id"] not in cited):
            out.append((r["id"], r["verdict"], cited.get(r["id"], ""), r["what was done"]))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("tsv", help="the campaign's TSV file")
    p.add_argument("--doc", default=os.path.join(ROOT, "docs", "reliability.md"))
    p.add_argument("--all", action="store_true", help="every row that is not ok")
    a = p.parse_args(argv)
    for path in (a.tsv, a.doc):
        if not os.path.isfile(path):
            print(f"campaign_status: error: {path}: no such file", file=sys.stderr)
            return 2
    rows = status(a.tsv, a.doc, a.all)
    for case_id, verdict, line, done in rows:
        where = "cited" if line else "NOT CITED"
        print(f"{case_id}\t{verdict}\t{where}\t{done[:100]}")
    uncited = sum(1 for r in rows if not r[2] and r[1] not in GOOD)
    print(f"{uncited} row(s) not ok or clear and not cited in {os.path.relpath(a.doc)}",
          file=sys.stderr)
    return 1 if uncited else 0


if __name__ == "__main__":
    sys.exit(main())
