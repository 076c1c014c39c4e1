"""The terminal report's findings table: a long size (an unexplained part's words) wraps within its column, so the
table stays within a terminal's width and every word is still there."""

from casadical.diagnosis._report import CELL_WIDTH
from casadical.diagnosis._words import table

LONG = "a part that follows the joint's load (as if k = 6.57e+04 N m/rad, progressive)"


def test_a_long_cell_wraps_within_its_column():
    rows = [["1", "compliance j2", "joint 2", "k2 = 5.68e4 N m/rad +- 3.6 %", "0.0258 mm better", "robot"],
            ["2", "unexplained j2 @b_cal", "joint 2", LONG, "kept out", "session"]]
    head, short, long = table(["#", "finding", "where", "size", "gain", "scope"], rows, right=(0,),
                              widest={2: CELL_WIDTH, 3: CELL_WIDTH})
    assert "\n" not in short and "\n" not in head
    lines = long.split("\n")
    assert len(lines) == 2
    start = head.index("size")
    assert head.index("gain") - start <= CELL_WIDTH + 2        # the column is no wider than its limit
    # the size's words in its column, one after the other; the row's other cells on its first line only
    assert " ".join(x[start:head.index("gain")].strip() for x in lines) == LONG
    assert "kept out" in lines[0] and lines[1][:start].strip() == "" and lines[1][head.index("gain"):].strip() == ""
    # without a limit the column is as wide as its widest cell (the table is one line per row)
    wide = table(["#", "size"], [["1", LONG]])
    assert wide[1].endswith(LONG) and len(wide) == 2
