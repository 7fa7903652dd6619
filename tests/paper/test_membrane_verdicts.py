"""The report's verdict for an ill-posed pair with the midpoint scheme (the paper's Figs. 3 and 4)
reads the paper's own sentence: "the energy is growing very fast after the first impact [...] the
instabilities are more important for the smallest time step"."""
import math

from sdm_dolfinx.paper.membrane_figures import unstable_verdict
from sdm_dolfinx.study.entry import Verdict


def test_the_smallest_time_step_growing_most_agrees_whatever_the_larger_ones_do():
    """The paper ranks the smallest dt against the others, not the larger ones among themselves: the
    P1/P0 growths measured on two machines (dt = 1e-2, 1e-3, 1e-4) both agree, the second one
    although 1e-3 grew a little less than 1e-2 (round-off amplified by an ill-posed pair)."""
    assert unstable_verdict([12.96, 13.30, 681.4]) is Verdict.AGREES
    assert unstable_verdict([12.96, 12.78, 851.7]) is Verdict.AGREES
    assert unstable_verdict([12.96, 12.78, math.inf]) is Verdict.AGREES      # blew up at the smallest dt


def test_growth_that_is_not_largest_at_the_smallest_step_or_no_growth_does_not():
    """The energy grows but the smallest dt is not the worst: in part. No growth (below 1.5 J0 at the
    smallest dt): not the paper's instability at all."""
    assert unstable_verdict([12.96, 851.7, 13.0]) is Verdict.IN_PART
    assert unstable_verdict([1.01, 1.02, 1.2]) is Verdict.DISAGREES
