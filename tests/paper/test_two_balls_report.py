"""The report's section "3-D: two balls against Hertz": its verdict follows the issue's 5 % criterion on the
finest level for both cases, its stored rows are read back only under the same definition, and its table
and sentence carry the rows' numbers (synthetic rows: the runs themselves are the quick report's, in
tests/integration/test_figures.py)."""
import json

from sdm_dolfinx.mpiutil import json_text
from sdm_dolfinx.report import two_balls_entry as entry
from sdm_dolfinx.study.entry import Verdict


def _row(case, level, err_t_c, err_F_max):
    return {"case": case, "level": level, "dt": 4e-5, "dofs": 1000 * level, "t_c": 3.9e-3 * (1 + err_t_c),
            "hertz_t_c": 3.9e-3, "err_t_c": err_t_c, "F_max": 3.161 * (1 + err_F_max), "hertz_F_max": 3.161,
            "err_F_max": err_F_max, "err_impulse": 0.002, "momentum_drift": 1e-13, "energy_drift": 0.002,
            "t": [0.0], "force": [0.0], "momentum": {}}


def test_the_verdict_is_the_finest_levels():
    coarse = [_row("head on", 1, 0.08, -0.03), _row("unequal", 1, 0.083, -0.032)]
    assert entry.ours(coarse)[1] is Verdict.IN_PART                     # t_c 8 % long, F_max within 5 %
    fine = coarse + [_row("head on", 2, 0.015, 0.002), _row("unequal", 2, 0.02, -0.01)]
    text, verdict = entry.ours(fine)
    assert verdict is Verdict.AGREES and "4 of 4 numbers are within 5 %" in text and "t_c +1.5 %" in text
    assert entry.ours(fine[:3] + [_row("unequal", 2, 0.06, 0.07)])[1] is Verdict.IN_PART
    assert entry.ours([_row("head on", 1, 0.2, 0.2)])[1] is Verdict.DISAGREES


def test_stored_rows_are_read_under_the_same_definition_only(tmp_path):
    rows = [_row("head on", 1, 0.08, -0.03)]
    (tmp_path / entry.ROWS_FILE).write_text(json_text({"key": entry.key(True), "rows": rows}))
    assert entry.read_rows(tmp_path, True) == json.loads(json_text(rows))
    assert entry.read_rows(tmp_path, False) is None                    # the full study: other levels
    (tmp_path / entry.ROWS_FILE).write_text("{not json")
    assert entry.read_rows(tmp_path, True) is None


def test_the_entry_has_the_table_and_the_figure():
    e = entry.make_entry([_row("head on", 1, 0.08, -0.03)], True, 12.0)
    assert e.key == "two_balls" and e.png == "two_balls/two_balls_hertz.png" and "Hertz" in e.says
    assert "<td>+8.0 %</td>" in e.html and "Computed in 12 s" in e.html
    assert "t" not in e.numbers["rows"][0] and e.numbers["rows"][0]["err_F_max"] == -0.03
