"""What ``make figures`` computes: the paper's study and the validation studies that join it in
the report (friction against rigid-body closed forms), as one list of runs."""
from dataclasses import dataclass

from sdm_dolfinx.paper.design import Study, make_study as make_paper_study
from sdm_dolfinx.validation.friction_study import FrictionStudy, friction_runs


@dataclass
class ReportStudy:
    """The paper's runs (:class:`~sdm_dolfinx.paper.design.Study`) and the friction runs."""
    paper: Study
    friction: FrictionStudy

    @property
    def quick(self):
        return self.paper.quick

    def runs(self):
        """Every run once: the paper's (cheapest figures first), then friction's."""
        seen = {r.name: r for r in self.paper.runs()}
        for r in self.friction.runs():
            seen.setdefault(r.name, r)
        return list(seen.values())


def make_study(quick=False, disc_max_level=None):
    """The runs of the full report (the paper's parameters) or of the quick one."""
    return ReportStudy(make_paper_study(quick, disc_max_level), friction_runs(quick))
