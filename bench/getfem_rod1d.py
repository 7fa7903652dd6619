"""GetFEM's demo_dynamic_contact_1D.py and sdm_dolfinx on the same rod with the same parameters.

The check the method comparison asks for: on the 1-D rod (``rod1d``: GetFEM's demo
and Dabaghi-Petrov-Pousin-Renard), the implicit Newmark scheme (beta = 1/4, gamma = 1/2, the
constraint on U^{n+1}: the demo's ``version = 0``) with the standard P1 mass and with the
redistributed mass, run by GetFEM's own script (Debian's ``python3-getfem``, run by the
system's ``/usr/bin/python3``, the script taken from a clone of GetFEM) and by sdm_dolfinx
(``scheme="newmark"``, pair P1/P1, ``mass="standard"`` / ``"redistributed"``). Compared per
time step: the displacement u(0, t) and the contact stress at x = 0 (GetFEM's ``s0`` is
u_x(0) = -lambda: its sign is flipped) and the energy.

What agreement means here:

* standard mass: both solve the same linear systems (GetFEM's "U1[0] < 0: impose U1[0] = 0"
  is the one-constraint LCP's solution), so they agree to the linear solvers' round-off;
* redistributed mass: GetFEM's demo moves M_00 and M_10 to M_11 and drops M_01, so its
  total mass is smaller than the rod's by M_01 = h/6 and its centre of mass moves; ours is
  Khenous-Laborde-Renard's redistribution, which keeps both (``sdm_dolfinx.method.masses``).
  The two differ by O(h): the script reports the difference and both errors against the
  exact solution, which is what can be compared.

    .venv/bin/python bench/getfem_rod1d.py             # NX = 20, 40, 80, dt = h / 25, T = 3 (a minute)
    .venv/bin/python bench/getfem_rod1d.py --demo PATH/demo_dynamic_contact_1D.py --NX 40 --dt-ratio 0.02

Results: ``bench/results/getfem_rod1d.json``.
"""
import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
#: where the `fetch` tool leaves GetFEM's repository on the development machines
MIRROR = Path("/work/.mirror/getfem-doc+getfem/repo")
DEMO = "interface/tests/python/demo_dynamic_contact_1D.py"
#: the exact solution's first impact (t = 1): before it both codes solve the same linear
#: systems; after it the standard mass's contact node chatters (Doyen-Ern-Piperno), and
#: round-off differences between the two codes' solvers grow without bound
FIRST_IMPACT = 1.0
#: "agree": |u0 difference| <= AGREE x u0(0)
AGREE = 1e-8
#: the demo's mass_matrix_type for each of our masses
MASSES = {"standard": 0, "redistributed": 1}


def demo_source(path):
    """The demo's text: ``path``, or the file in the GetFEM clone at :data:`MIRROR`."""
    if path is not None:
        return Path(path).read_text()
    try:
        return subprocess.run(["git", "-C", str(MIRROR), "show", f"HEAD:{DEMO}"], check=True,
                              capture_output=True, text=True).stdout
    except (OSError, subprocess.CalledProcessError):
        sys.exit(f"getfem_rod1d: GetFEM's {DEMO} not found in {MIRROR}; give it with --demo PATH")


#: the demo's sparse solve, which segfaults in Debian 12's GetFEM 5.4.2 (python3-getfem
#: 5.4.2+dfsg1-3+b1: ``gf.linsolve_superlu`` on the first time step, measured 2026-11-24) ...
SUPERLU = """def linsolve(M, B): # Call Superlu to solve a sparse linear system
    return (((gf.linsolve_superlu(M, B))[0]).T)[0]"""
#: ... replaced by a dense solve of the same GetFEM matrix (the rod has NX + 1 dofs)
DENSE = """def linsolve(M, B):
    return np.linalg.solve(M.full(), B)"""


def run_getfem(source, NX, dt, T, mass, work):
    """Run GetFEM's demo (implicit Newmark, pure Signorini) in a subprocess, its sparse solve
    replaced by a dense one (:data:`SUPERLU`); its stored series."""
    if SUPERLU not in source:
        sys.exit("getfem_rod1d: the demo's linsolve is not the one this script replaces; check the demo's version")
    script = Path(work) / "demo.py"
    script.write_text(source.replace(SUPERLU, DENSE))
    out = Path(work) / mass
    args = [f"NX={NX}", f"dt={dt}", f"T={T}", "u_degree=1", "version=0", "beta=0.25", "gamma=0.5",
            f"mass_matrix_type={MASSES[mass]}", "lump_mass_matrix=0", "do_final_plot=False",
            "do_inter_plot=False", "do_export_in_files=True", f"output_directory='{out}'"]
    proc = subprocess.run(["/usr/bin/python3", str(script), *args], capture_output=True, text=True,
                          env={"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"})
    if proc.returncode:
        sys.exit(f"getfem_rod1d: GetFEM's demo failed ({mass}): {proc.stderr.strip().splitlines()[-1:]}"
                 f" (is python3-getfem installed? apt-get install python3-getfem)")
    return {k: np.load(out / f"dyn1d.{k}.npy") for k in ("u0", "s0", "E")}


def run_ours(NX, dt, T, mass):
    """The same run with sdm_dolfinx (1 rank); its time series."""
    from mpi4py import MPI
    from sdm_dolfinx.run import simulate
    r = simulate("rod1d", {"NX": NX}, comm=MPI.COMM_SELF, pair="P1/P1", mass=mass, scheme="newmark", dt=dt, T=T)
    ts = r.timeseries
    return {"u0": np.asarray(ts["u_probe"]), "s0": -np.asarray(ts["lambda_probe"]), "E": np.asarray(ts["energy"])}


def exact_series(t):
    """u(0, t) and u_x(0, t) of the closed form (``sdm_dolfinx.problems.rod1d``)."""
    from mpi4py import MPI
    from sdm_dolfinx.problems import get
    spec = get("rod1d")
    ex = spec.exact(spec.problem(MPI.COMM_SELF, NX=2))
    x0 = np.zeros((3, 1))
    u = np.array([float(np.ravel(ex.displacement(x0, ti))[0]) for ti in t])
    return u, -np.array([float(ex.contact_stress(ti)) for ti in t])


def compare(NX, dt, T, source):
    records = []
    with tempfile.TemporaryDirectory() as work:
        for mass in MASSES:
            g, o = run_getfem(source, NX, dt, T, mass, work), run_ours(NX, dt, T, mass)
            n = min(len(g["u0"]), len(o["u0"]))
            t = dt * np.arange(n)
            u_ex, s_ex = exact_series(t)
            rec = {"mass": mass, "NX": NX, "dt": dt, "T": T, "steps_compared": n - 1}
            for k in ("u0", "s0", "E"):
                diff = np.abs(g[k][:n] - o[k][:n])
                rec[f"max_diff_{k}"] = float(np.max(diff))
                rec[f"max_diff_{k}_before_impact"] = float(np.max(diff[t < FIRST_IMPACT]))
            # the first time u(0) differs by more than AGREE x its initial value 1/2
            off = np.nonzero(np.abs(g["u0"][:n] - o["u0"][:n]) > AGREE * 0.5)[0]
            rec["u0_agrees_until"] = float(t[off[0]]) if off.size else float(t[-1])
            for who, s in (("getfem", g), ("ours", o)):
                rec[f"{who}_L2_error_u0"] = float(np.sqrt(dt * np.sum((s["u0"][:n] - u_ex) ** 2) / T))
                rec[f"{who}_L2_error_s0"] = float(np.sqrt(dt * np.sum((s["s0"][:n] - s_ex) ** 2) / T))
                rec[f"{who}_energy_at_T"] = float(s["E"][n - 1])
            records.append(rec)
            print(json.dumps(rec), flush=True)
    return records


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--demo", default=None, help=f"GetFEM's {DEMO} (default: from {MIRROR})")
    p.add_argument("--NX", type=int, nargs="+", default=[20, 40, 80], help="cells (several: a convergence series)")
    p.add_argument("--dt-ratio", type=float, default=0.04, help="dt = ratio x h (default 0.04: the demo's 2e-3 at NX 20)")
    p.add_argument("--T", type=float, default=3.0)
    p.add_argument("--out", type=Path, default=HERE / "results" / "getfem_rod1d.json")
    a = p.parse_args(argv)
    source = demo_source(a.demo)
    records = [r for nx in a.NX for r in compare(nx, a.dt_ratio / nx, a.T, source)]
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps({"records": records}, indent=1) + "\n")
    print(f"written {a.out}")


if __name__ == "__main__":
    main()
