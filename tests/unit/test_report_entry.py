"""The report's entries carry their verdict as a value: the summary, numbers.json and each section's
colour follow ``Entry.verdict`` whatever the sentences say, and an entry refuses a verdict that is
not a :class:`~sdm_dolfinx.study.entry.Verdict`."""
import json

from mpi4py import MPI

import pytest

from sdm_dolfinx.errors import SdmError
from sdm_dolfinx.report import build
from sdm_dolfinx.study.entry import Entry, EntryError, Verdict

COMM = MPI.COMM_WORLD


def test_verdict_of_truth_values():
    """ok wins over partly; the values are numbers.json's strings."""
    assert Verdict.of(True) is Verdict.AGREES and Verdict.of(True, True) is Verdict.AGREES
    assert Verdict.of(False, True) is Verdict.IN_PART
    assert Verdict.of(False) is Verdict.DISAGREES and Verdict.of(False, False) is Verdict.DISAGREES
    assert [v.value for v in Verdict] == ["agrees", "in part", "does not agree"]


def test_paragraph_ends_with_the_verdicts_sentence():
    """Our paragraph is the findings, one space, then the sentence of the verdict."""
    e = Entry("fig02", "Ours: the energy is conserved. ", Verdict.IN_PART)
    assert e.ours == "Ours: the energy is conserved. Ours agrees in part."
    assert Entry("x", "Ours: n = 3.", Verdict.DISAGREES, says="s").ours == "Ours: n = 3. Ours does not agree."
    assert Entry("x", "", Verdict.AGREES, says="s").ours == "Ours agrees."


@pytest.mark.parametrize("verdict", ["agrees", "Ours agrees.", "yes", True, None, 1])
def test_entry_refuses_an_unknown_verdict(verdict):
    with pytest.raises(EntryError) as err:
        Entry("fig02", "Ours: something.", verdict)
    assert isinstance(err.value, SdmError)
    msg = str(err.value)
    assert "\n" not in msg and "'fig02'" in msg and "Verdict.AGREES" in msg


@pytest.mark.parametrize("key, numbers", [("", {}), (None, {}), ("fig02", [1, 2]), ("fig02", None)])
def test_entry_refuses_a_key_or_numbers_it_cannot_report(key, numbers):
    with pytest.raises(EntryError):
        Entry(key, "Ours: something.", Verdict.AGREES, numbers=numbers)


class _Study:
    """What write_report reads of a study: the mode and the runs (none here)."""
    quick = True

    @staticmethod
    def runs():
        return []


def _write(folder, entries):
    """index.html and numbers.json of ``entries`` (the last one standing for Table 2's)."""
    meta = {"ranks": 1, "wall": 1.0, "computed": 0, "cached": 0, "runs_total": 0.0, "command": "test",
            "versions": "test", "runs_dir": folder}
    build.write_report(folder, entries, entries[-1], [], {}, _Study(), meta)
    return (folder / "index.html").read_text(), json.loads((folder / "numbers.json").read_text())


def test_a_reworded_sentence_does_not_change_the_verdict(mpi_tmp_path):
    """Findings that say "Ours agrees." under the verdict DISAGREES are summarised as "does not agree"
    (summary table, numbers.json, the section's colour), and the other way round."""
    entries = [Entry("fig02", "Ours: everything matches. Ours agrees.", Verdict.DISAGREES, numbers={"n": 1}),
               Entry("fig03", "Ours: nothing matches. Ours does not agree. Ours agrees in part.", Verdict.AGREES),
               Entry("table2", "Ours: rows 1-3. Ours does not agree.", Verdict.IN_PART, numbers={"rows": [1]})]
    if COMM.rank == 0:
        page, numbers = _write(mpi_tmp_path, entries)
        assert numbers["verdicts"] == {"fig02": "does not agree", "fig03": "agrees", "table2": "in part"}
        assert numbers["figures"] == {"fig02": {"n": 1}, "fig03": {}, "table2": {"rows": [1]}}
        assert numbers["table2"] == {"rows": [1]}
        for key, verdict, css in (("fig02", "does not agree", "v-no"), ("fig03", "agrees", "v-yes"),
                                  ("table2", "in part", "v-part")):
            assert f"<tr><td>{key}</td><td>{verdict}</td></tr>" in page
            assert f"<section class='{css}' id='{key}'>" in page
        assert "<p class='ours'>Ours: everything matches. Ours agrees. Ours does not agree.</p>" in page
        assert build.summary(entries) == [("fig02", "does not agree"), ("fig03", "agrees"), ("table2", "in part")]
    COMM.Barrier()
