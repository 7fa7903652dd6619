"""A problem file for tests/integration/test_obstacle_files.py: a body on a floor that rises as
s(t) = lift (1 - cos(omega t)) (a HalfSpace moved by ``motion``), beside a fixed obstacle it does not
touch. dim = 2: the block (20 x 10 mm, 8 x 4 squares) on the floor y = s(t), a disc of radius 2 centred
at (30, 5) beside it. dim = 3: the ball (level 1) above the plane z = s(t), a fixed sphere of radius 4
centred at (30, 0, 20) beside it."""
import numpy as np

from sdm_dolfinx.obstacles import Ball, HalfSpace
from sdm_dolfinx.problems import Param, ProblemSpec, ball, block


def floor(lift, omega):
    """The rising floor's translation s(t) (a vector along y (2-D) or z (3-D) is made by the caller)."""
    return lambda t: lift * (1.0 - np.cos(omega * t))


def build(comm, dim, lift, omega):
    s = floor(lift, omega)
    if dim == 2:
        p = block.problem(comm, nx=8, ny=4)
        p.obstacles = [HalfSpace((0.0, 0.0), (0.0, 1.0), motion=lambda t: (0.0, s(t))), Ball((30.0, 5.0), 2.0)]
    else:
        p = ball.problem(comm, level=1, height=0.001)
        p.obstacles = [HalfSpace((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), motion=lambda t: (0.0, 0.0, s(t))),
                       Ball((30.0, 0.0, 20.0), 4.0)]
    p.lower_bound, p.moving_bound, p.name = None, False, "rising_floor"
    return p


PROBLEM = ProblemSpec(
    name="rising_floor", build=build, doc=__doc__,
    params=(Param("dim", 2, "2: the block, 3: the ball", type=int, low=2, high=3),
            Param("lift", 0.5, "the floor's rise amplitude", unit="mm", low=0.0),
            Param("omega", 200.0, "its angular frequency", unit="rad/s", low=0.0)))
