"""What a run assumes constant, and a check that it stayed so.

A is assembled and factorised once, L once (unless the Problem declares ``time``), and the
bounds and Dirichlet values are evaluated once: a ``fem.Constant`` or ``fem.Function`` of
those forms, or a callable, that a user changes during the run (in ``on_step``, say) would
otherwise have no effect at all. :class:`FrozenData` keeps their values at the start and
names the first one that changed; the integrator checks before every step (one small
collective) and stops the run with that line. While user code runs during a run (``on_step``,
``observe``), the forms themselves are rebuilt and compared too (:meth:`FrozenData.watch_forms`):
a plain Python number that a(u, w) or l(w) reads, changed by that code, is a literal of the form.
"""
from mpi4py import MPI

import numpy as np

from sdm_dolfinx.problems.density import is_field


def _literals(form):
    """The values of a UFL form's scalar literals (the Python numbers its integrands read), sorted: a
    multiset that does not depend on the order UFL keeps a sum's or a product's operands in. (The form's
    signature did: a rebuilt, unchanged form's signature was measured to differ from the assembled one's
    in the middle of the test suite, a change reported where nothing had changed.)"""
    from ufl.constantvalue import ScalarValue
    from ufl.corealg.traversal import pre_traversal
    values = [complex(e.value()) for integral in form.integrals() for e in pre_traversal(integral.integrand())
              if isinstance(e, ScalarValue)]
    values += [complex(v) for integral in form.integrals() for v in integral.metadata().values()   # a degree
               if isinstance(v, (int, float)) and not isinstance(v, bool)]
    return np.sort(np.array(values, dtype=complex))


def _form_data(form, where, hint):
    """(label, current value) getters of the Constants and Functions of a UFL form."""
    items = []
    for c in form.constants():
        items.append((f"the Constant {c} of {where}", lambda c=c: np.array(c.value, copy=True), hint, True))
    for f in form.coefficients():
        name = getattr(f, "name", None) or str(f)
        items.append((f"the Function {name!r} of {where}", lambda f=f: f.x.array.copy(), hint, False))
    return items


class FrozenData:
    """The data of a Discretisation assembled or evaluated once, with their values at the start.

    Args:
        problem: the Problem.
        a_form, l_form: the UFL forms a(u, w) and l(w) as assembled.
        cx: coordinates (3, n) of the owned constrained vertices (the bound is checked there);
            None when the problem has no constraint anywhere.
        xd: coordinates (3, n) of the owned Dirichlet dofs; None without Dirichlet data.
        comm: the mesh's communicator.
    """

    def __init__(self, problem, a_form, l_form, cx, xd, comm):
        self.comm, self.problem, self.forms = comm, problem, (a_form, l_form)
        items = _form_data(a_form, "a(u, w)", "A is assembled once: a stiffness that changes during a run is "
                                              "not supported")
        if problem.time is None:
            items += _form_data(l_form, "l(w)", "L is assembled once unless the Problem declares its time "
                                                "dependence: Problem(time=t), t a fem.Constant used by l(w)")
        if cx is not None and problem.lower_bound is not None and not getattr(problem, "moving_bound", False):
            # a moving bound is evaluated every step; obstacles and contact pairs have none
            items.append(("the bound lower_bound(x) at the constrained vertices",
                          lambda: np.asarray(problem.lower_bound(cx), dtype=float).copy(),
                          "a bound that moves must say so: Problem(moving_bound=True), lower_bound(x, t)", False))
        if is_field(problem.rho):
            items.append(("the density rho (a Function)", lambda: np.array(problem.rho.x.array, copy=True),
                          "the mass is assembled once: a density that changes during a run is not supported", False))
        if xd is not None:
            items.append(("dirichlet_value(x) on the Dirichlet boundary",
                          lambda: np.asarray(problem.dirichlet_value(xd), dtype=float).copy(),
                          "a dirichlet_value that moves is not supported: declare moving data as a Dirichlet "
                          "part (Problem.dirichlet_parts, value(x, t))", False))
        self.items = items
        self.start = [get() for _, get, _, _ in items]

    def __len__(self):
        return len(self.items)

    def watch_forms(self):
        """From now on also compare a(u, w) and l(w), rebuilt from the Problem before every step, with
        the forms assembled (the values of their literals, :func:`_literals`: a Python number in a form is
        one): a number that user code changes during the run would otherwise be ignored. About 0.2-0.5 ms per step,
        so the run asks for it only when it calls user code (``on_step``, ``observe``)."""
        a_form, l_form = self.forms
        w, u = sorted(a_form.arguments(), key=lambda arg: arg.number())
        for label, form, build, hint in (
                ("a(u, w)", a_form, lambda: self.problem.a(u, w),
                 "A is assembled once: a stiffness that changes during a run is not supported"),
                ("l(w)", l_form, lambda: self.problem.l(w),
                 "L is assembled once: a load that changes must be a fem.Constant of l(w) and the Problem must "
                 "declare its time (Problem(time=t)), so that L is reassembled every step")):
            self.items.append((f"a Python number read by {label}", lambda build=build: _literals(build()), hint,
                               False))
            self.start.append(_literals(form))

    def changed(self):
        """None, or one line naming the first datum whose value differs from the start (collective)."""
        if not self.items:
            return None
        first = len(self.items)
        for k, (_, get, _, _) in enumerate(self.items):
            now = get()
            if now.shape != self.start[k].shape or not np.array_equal(now, self.start[k]):
                first = k
                break
        first = self.comm.allreduce(first, op=MPI.MIN)
        if first == len(self.items):
            return None
        label, get, hint, show = self.items[first]
        values = f" (from {_fmt(self.start[first])} to {_fmt(get())})" if show else ""
        return f"{label} changed during the run{values}; {hint}"


def _fmt(v):
    v = np.asarray(v)
    return f"{float(v):g}" if v.shape == () else "(" + ", ".join(f"{x:g}" for x in v.reshape(-1)) + ")"
