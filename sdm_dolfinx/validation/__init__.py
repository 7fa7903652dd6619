"""Studies against closed forms beyond the paper, each resumable and in the report.

3-D: :mod:`.hertz` (the ball against Hertz: contact time, peak force, approach, pressure profile;
:mod:`.ball_pictures` draws it) and :mod:`.ball_oblique` (the oblique impact with Coulomb friction:
impulses, rebound, spin). Friction in 2-D: :mod:`.friction_study` (the runs),
:mod:`.friction_rigid` (the disc on an incline and the sliding block against rigid-body closed
forms) and :mod:`.friction_impact` (the disc's oblique impact, sticking and sliding).
"""
