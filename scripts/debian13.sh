#!/usr/bin/env bash
# Run sdm_dolfinx on current FEniCSx in a Debian 13 (trixie) chroot, beside the host's dolfinx 0.5.2
# (Debian 12). Two versions share one root file system:
#   SDM_DOLFINX=0.9 (default)  Debian 13's own python3-dolfinx 0.9 (PETSc 3.22, Open MPI);
#   SDM_DOLFINX=0.11           PyPI's binary wheel dolfinx-solver-real 0.11 (PETSc 3.25 with MUMPS
#                              but neither SuiteSparse nor hypre, MPICH, numpy 2), in a venv without
#                              system packages (/opt/sdm-dolfinx011), as a user of that wheel has it.
#
#   scripts/debian13.sh [test]       build the root file system if needed, then run the pytest
#                                    suite on 1 rank and on $NP (default 2) ranks inside it, then
#                                    compare a membrane run between the host's dolfinx and this one
#   scripts/debian13.sh versions     only that comparison (tests/integration/test_versions.py)
#   scripts/debian13.sh build        only build (or check) the root file system (and the 0.11 venv)
#   scripts/debian13.sh run CMD ...  run CMD inside it, in the checkout (e.g. python3 demos/x.py;
#                                    with SDM_DOLFINX=0.11, python3 and mpirun are the venv's)
#   scripts/debian13.sh shell        an interactive shell inside it
#
# The root file system is built once with `debootstrap --variant=minbase trixie` from the Debian
# mirror the host's apt uses, plus Debian's python3-dolfinx and the packages the project uses,
# and cached in $SDM_TRIXIE_ROOTFS (default /var/cache/sdm_dolfinx/trixie-rootfs; ~3.2 GB,
# ~5 minutes). A stamp file beside it marks it complete: without the stamp (an interrupted build)
# it is rebuilt from scratch; SDM_TRIXIE_REBUILD=1 forces that. The 0.11 venv is made inside it
# on first use (pip, ~1 min, ~700 MB) and remade when its requirements below change. The checkout
# is bound at /src/sdm_dolfinx and put on PYTHONPATH (no pip install), the paper's GetFEM meshes
# (when found beside the checkout, as the tests look for them) at /src/shared/data; /proc, /sys,
# /dev, a tmpfs /dev/shm and a tmpfs /tmp are mounted, and every mount is undone on exit, failure
# or interruption. Needs root (debootstrap, mount, chroot). Runs are serialised by a lock beside
# the rootfs. SERIAL_MARK and MPI_MARK: pytest -m expressions selecting the 1-rank and $NP-rank legs' tests.
set -euo pipefail

SRC=$(cd "$(dirname "$0")/.." && pwd)
ROOTFS=${SDM_TRIXIE_ROOTFS:-/var/cache/sdm_dolfinx/trixie-rootfs}
ROOTFS=${ROOTFS%/}
case "$ROOTFS" in
  /?*/?*) ;;
  *) echo "debian13: SDM_TRIXIE_ROOTFS must be an absolute path at least two levels deep (got '$ROOTFS')" >&2; exit 2 ;;
esac
STAMP="$ROOTFS.stamp"
MARKER=.sdm_dolfinx_rootfs       # inside the rootfs: made by this script, safe to delete
LOCK="$ROOTFS.lock"
SUITE=trixie
NP=${NP:-2}
JOBS=${JOBS:-2}      # the 1-rank suite in JOBS pytest-xdist workers (as the Makefile's test-serial)
INNER_SRC=/src/sdm_dolfinx
# Debian packages the project uses (the same set scripts/setup.sh installs on Debian 12, minus
# the venv tools: the chroot imports the checkout through PYTHONPATH). libopenblas0-serial: as on
# the host, MUMPS gets OpenBLAS through Debian's alternatives instead of the reference BLAS.
PACKAGES="python3-dolfinx python3-petsc4py python3-mpi4py python3-h5py python3-matplotlib
python3-scipy python3-gmsh python3-pytest python3-pytest-xdist openmpi-bin libopenblas0-serial python3-venv
python3-adios2-serial"
PACKAGES=$(echo $PACKAGES)        # one line, single spaces (it is also the stamp's content)
# python3-venv: for the 0.11 venv; python3-adios2-serial: ADIOS2's Python bindings, which read the VTX
# files back (tests/cli/test_vtx_command.py). The venv's requirements, as a user of the wheel installs
# them: the wheel pinned (a new one is a new dolfinx), the rest as pip resolves them against it (adios2:
# the same reading, never imported beside dolfinx).
DOLFINX=${SDM_DOLFINX:-0.9}
VENV=/opt/sdm-dolfinx011
VENV_REQUIREMENTS="dolfinx-solver-real==0.11.0.post0 h5py scipy matplotlib pytest pytest-xdist gmsh adios2"
case "$DOLFINX" in
  0.9) INNER_PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin ;;
  0.11) INNER_PATH=$VENV/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin ;;
  *) echo "debian13: SDM_DOLFINX must be 0.9 or 0.11 (got '$DOLFINX')" >&2; exit 2 ;;
esac
# pytest -m expressions choosing the tests of each leg (empty: all)
SERIAL_MARK=${SERIAL_MARK:-}
MPI_MARK=${MPI_MARK:-}
SERIAL_ARGS=(); [ -n "$SERIAL_MARK" ] && SERIAL_ARGS=(-m "$SERIAL_MARK")
MPI_ARGS=(); [ -n "$MPI_MARK" ] && MPI_ARGS=(-m "$MPI_MARK")

T0=$SECONDS
exec 3>&1 4>&2      # the terminal, for messages from traps (which may run inside a redirection)
say() { printf '[dolfinx %s %4ds] %s\n' "$DOLFINX" "$((SECONDS - T0))" "$*"; }
die() { echo "debian13: $*" >&2; exit 2; }

cmd=${1:-test}
[ $# -gt 0 ] && shift
case "$cmd" in
  test|build|shell|versions) ;;
  run) [ $# -gt 0 ] || die "run needs a command, e.g. scripts/debian13.sh run python3 -c 'import dolfinx'" ;;
  -h|--help|help) sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
  *) die "unknown command '$cmd' (test, versions, build, run CMD..., shell)" ;;
esac

[ "$(id -u)" -eq 0 ] || die "needs root (debootstrap, mount and chroot): run it as root or with sudo"

# ----------------------------------------------------------------------------- mounts
mounts_under() {   # mount points at or below $ROOTFS, deepest first
  awk '{print $5}' /proc/self/mountinfo | sed 's/\\040/ /g' \
    | awk -v r="$ROOTFS" 'substr($0, 1, length(r)) == r && (length($0) == length(r) || substr($0, length(r) + 1, 1) == "/")' \
    | sort -r
}

unmount_all() {
  local m
  mounts_under | while IFS= read -r m; do
    umount "$m" 2>/dev/null || umount -l "$m" 2>/dev/null || echo "debian13: could not unmount $m" >&4
  done
}

CHILD=""
descendants() { local c; for c in $(ps -o pid= --ppid "$1" 2>/dev/null); do descendants "$c"; echo "$c"; done; }
stop_child() {    # TERM the running child and everything it started, KILL what survives 5 s
  local pids p
  [ -n "$CHILD" ] && kill -0 "$CHILD" 2>/dev/null || return 0
  pids="$(descendants "$CHILD") $CHILD"
  kill -TERM $pids 2>/dev/null || true
  for _ in 1 2 3 4 5 6 7 8 9 10; do
    for p in $pids; do kill -0 "$p" 2>/dev/null && break; p=""; done
    [ -z "$p" ] && break
    sleep 0.5
  done
  kill -KILL $pids 2>/dev/null || true
  wait "$CHILD" 2>/dev/null || true
}
cleanup() {
  local rc=$?
  trap - EXIT INT TERM
  stop_child
  if [ -n "$(mounts_under)" ]; then
    unmount_all
    [ -z "$(mounts_under)" ] && say "mounts undone" >&3 || echo "debian13: mounts left under $ROOTFS" >&4
  fi
  exit "$rc"
}
trap cleanup EXIT
trap 'echo "debian13: interrupted" >&4; exit 130' INT
trap 'echo "debian13: terminated" >&4; exit 143' TERM

mount_system() {   # the kernel file systems a chroot needs (apt's maintainer scripts, MPI)
  mount -t proc proc "$ROOTFS/proc"
  mount --rbind /sys "$ROOTFS/sys"; mount --make-rslave "$ROOTFS/sys"
  mount --bind /dev "$ROOTFS/dev"
  mkdir -p "$ROOTFS/dev/shm"       # /dev/shm of the host is not shared: a fresh tmpfs
  mount -t tmpfs -o mode=1777,nosuid,nodev shm "$ROOTFS/dev/shm"
  mkdir -p "$ROOTFS/dev/pts"
  mount -t devpts -o newinstance,ptmxmode=0666 devpts "$ROOTFS/dev/pts" 2>/dev/null || true
  mount -t tmpfs -o mode=1777 tmp "$ROOTFS/tmp"
}

# Run a command in the background and wait for it, so that a signal reaches our trap at once
# (bash runs traps only between foreground commands).
run_bg() {
  local rc=0
  "$@" <&0 &
  CHILD=$!
  wait "$CHILD" || rc=$?
  CHILD=""
  return "$rc"
}

# The environment inside the chroot: the checkout on PYTHONPATH, OpenMPI allowed to run as
# root over shared memory (as the Makefile sets it); OMPI_MCA_* of the caller override.
chroot_env() {
  local v
  CHROOT_ENV=(PATH="$INNER_PATH" HOME=/root LANG=C.UTF-8
    TERM="${TERM:-dumb}" DEBIAN_FRONTEND=noninteractive PYTHONPATH="$INNER_SRC" PYTHONDONTWRITEBYTECODE=1
    OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl=self,vader
    OMPI_MCA_rmaps_base_oversubscribe=1)
  [ -n "${CI:-}" ] && CHROOT_ENV+=("CI=$CI")
  for v in $(compgen -e); do
    case "$v" in OMPI_MCA_*|PRTE_MCA_*|PMIX_MCA_*) CHROOT_ENV+=("$v=${!v}") ;; esac
  done
}

# Run a command inside the chroot, in the checkout.
in_chroot() {
  chroot_env
  run_bg chroot "$ROOTFS" /usr/bin/env -i "${CHROOT_ENV[@]}" /bin/sh -c 'cd "$0" && exec "$@"' "$INNER_SRC" "$@"
}

# ----------------------------------------------------------------------------- mirror
host_mirror() {   # the host's Debian archive URI (deb822 .sources or one-line .list files)
  local codename f
  codename=$(. /etc/os-release && echo "${VERSION_CODENAME:-}")
  for f in /etc/apt/sources.list.d/*.sources; do
    [ -f "$f" ] || continue
    awk -v cn="$codename" '
      function flush() { if (types ~ /(^| )deb( |$)/ && (" " suites " ") ~ (" " cn " ") && uri != "") { print uri; found = 1; exit } types = suites = uri = "" }
      /^[ \t]*#/ { next }
      /^[ \t]*$/ { flush(); next }
      tolower($1) == "types:" { $1 = ""; types = $0 }
      tolower($1) == "suites:" { $1 = ""; suites = $0 }
      tolower($1) == "uris:" { uri = $2 }
      END { if (!found) flush() }' "$f"
  done
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
    [ -f "$f" ] || continue
    # deb [options] URI suite components
    sed -e 's/#.*//' -e 's/\[[^]]*\]//' "$f" | awk -v cn="$codename" '$1 == "deb" && $3 == cn { print $2 }'
  done
}

# ----------------------------------------------------------------------------- build
build_rootfs() {
  local mirror t
  mirror=${SDM_DEBIAN_MIRROR:-$(host_mirror | head -n 1)}
  [ -n "$mirror" ] || die "no Debian mirror found in /etc/apt/sources.list*; set SDM_DEBIAN_MIRROR"
  if ! command -v debootstrap >/dev/null; then
    say "installing debootstrap on the host"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq debootstrap >/dev/null
  fi
  rm -f "$STAMP"
  if [ -e "$ROOTFS" ]; then
    # only ever delete a folder this script made (it carries our marker) or an empty one
    [ -e "$ROOTFS/$MARKER" ] || [ -z "$(ls -A "$ROOTFS" 2>/dev/null)" ] \
      || die "$ROOTFS exists and was not made by this script; remove it or set SDM_TRIXIE_ROOTFS"
    say "removing the incomplete root file system $ROOTFS"
    unmount_all
    [ -z "$(mounts_under)" ] || die "mounts remain under $ROOTFS; not removing it"
    rm -rf --one-file-system "$ROOTFS"
  fi
  mkdir -p "$ROOTFS"
  touch "$ROOTFS/$MARKER"
  say "phase 1/3: debootstrap --variant=minbase $SUITE from $mirror"
  t=$SECONDS
  run_bg debootstrap --variant=minbase "$SUITE" "$ROOTFS" "$mirror" > "$ROOTFS.debootstrap.log" 2>&1 \
    || { tail -n 20 "$ROOTFS.debootstrap.log" >&2; die "debootstrap failed (log: $ROOTFS.debootstrap.log)"; }
  say "debootstrap done in $((SECONDS - t)) s"
  # maintainer scripts must not start services; name resolution as on the host
  printf '#!/bin/sh\nexit 101\n' > "$ROOTFS/usr/sbin/policy-rc.d"
  chmod 755 "$ROOTFS/usr/sbin/policy-rc.d"
  cp -L /etc/resolv.conf "$ROOTFS/etc/resolv.conf" 2>/dev/null || true
  install_packages
}

install_packages() {
  local t
  say "phase 2/3: apt-get install $PACKAGES"
  t=$SECONDS
  mkdir -p "$ROOTFS$INNER_SRC"
  mount_system
  in_chroot sh -c "apt-get update -q && apt-get install -y -q $PACKAGES && apt-get clean" \
    > "$ROOTFS.install.log" 2>&1 \
    || { tail -n 30 "$ROOTFS.install.log" >&2; die "package installation failed (log: $ROOTFS.install.log)"; }
  unmount_all
  say "packages installed in $((SECONDS - t)) s; root file system: $(du -sh --one-file-system "$ROOTFS" | cut -f1)"
  echo "$PACKAGES" > "$STAMP"
}

# Serialise runs: two at once would share the mount points (and one build is plenty).
mkdir -p "$(dirname "$ROOTFS")"
exec 9> "$LOCK"
if ! flock -n 9; then
  say "another debian13.sh run holds $LOCK; waiting"
  flock 9
fi
unmount_all        # leftovers of a run killed with SIGKILL

if [ "${SDM_TRIXIE_REBUILD:-0}" = 1 ]; then
  rm -f "$STAMP"
fi
if [ ! -f "$STAMP" ] || [ ! -x "$ROOTFS/usr/bin/python3" ]; then
  say "building the $SUITE root file system in $ROOTFS"
  build_rootfs
elif [ "$(cat "$STAMP")" != "$PACKAGES" ]; then
  say "the package list changed: installing into the existing root file system"
  install_packages
else
  say "reusing $ROOTFS (complete: $STAMP)"
fi

# ----------------------------------------------------------------------------- the 0.11 venv
VENV_STAMP="$ROOTFS$VENV.stamp"
ensure_venv() {   # (the mounts are up) make the 0.11 venv if it is missing or its requirements changed
  local t
  if [ -x "$ROOTFS$VENV/bin/python" ] && [ "$(cat "$VENV_STAMP" 2>/dev/null)" = "$VENV_REQUIREMENTS" ]; then
    say "reusing the venv $VENV"
    return 0
  fi
  say "making the venv $VENV: pip install $VENV_REQUIREMENTS"
  t=$SECONDS
  rm -rf "${ROOTFS:?}$VENV" "$VENV_STAMP"
  # pip trusts the host's certificate authorities (a machine behind a TLS-inspecting proxy has its own)
  local cert=""
  if [ -f /etc/ssl/certs/ca-certificates.crt ]; then
    cp /etc/ssl/certs/ca-certificates.crt "$ROOTFS/etc/ssl/host-ca-certificates.crt"
    cert="PIP_CERT=/etc/ssl/host-ca-certificates.crt"
  fi
  in_chroot env $cert sh -c "/usr/bin/python3 -m venv $VENV && $VENV/bin/python -m pip install -q --no-cache-dir $VENV_REQUIREMENTS" \
    > "$ROOTFS.venv011.log" 2>&1 \
    || { tail -n 30 "$ROOTFS.venv011.log" >&2; die "pip install failed (log: $ROOTFS.venv011.log)"; }
  echo "$VENV_REQUIREMENTS" > "$VENV_STAMP"
  say "venv made in $((SECONDS - t)) s"
}

# The paper's GetFEM meshes, looked for as the tests look for them (sdm_dolfinx/paper/design.py:
# $SDM_GETFEM_MESHES, then shared/data/getfem-disc-meshes beside the checkout or one of its parents).
paper_meshes() {
  local d=$SRC
  if [ -n "${SDM_GETFEM_MESHES:-}" ] && [ -d "$SDM_GETFEM_MESHES" ]; then echo "$SDM_GETFEM_MESHES"; return; fi
  while [ "$d" != / ]; do
    d=$(dirname "$d")
    [ -d "$d/shared/data/getfem-disc-meshes" ] && { echo "$d/shared/data/getfem-disc-meshes"; return; }
  done
}

# ----------------------------------------------------------------------------- use
mkdir -p "$ROOTFS$INNER_SRC"
mount_system
mount --bind "$SRC" "$ROOTFS$INNER_SRC"
MESHES=$(paper_meshes)
if [ -n "$MESHES" ]; then
  mkdir -p "$ROOTFS/src/shared/data/getfem-disc-meshes"
  mount --bind "$MESHES" "$ROOTFS/src/shared/data/getfem-disc-meshes"
  say "the paper's GetFEM meshes: $MESHES (at /src/shared/data/getfem-disc-meshes)"
else
  say "the paper's GetFEM meshes were not found beside $SRC: their tests skip"
fi
[ "$DOLFINX" = 0.11 ] && ensure_venv
say "phase 3/3: $cmd in the chroot ($SRC bound at $INNER_SRC)"
# mpi4py first: the wheel's dolfinx finds its MPI library only once mpi4py (or dolfinx_solver) has loaded it
in_chroot python3 -c 'from mpi4py import MPI
import dolfinx, basix, ufl, ffcx, petsc4py, mpi4py
from petsc4py import PETSc
print("dolfinx", dolfinx.__version__, "| basix", basix.__version__, "| ufl", ufl.__version__, "| ffcx", ffcx.__version__,
      "| PETSc", ".".join(map(str, PETSc.Sys.getVersion())), "| petsc4py", petsc4py.__version__,
      "| mpi4py", mpi4py.__version__, "|", MPI.Get_library_version().splitlines()[0])' \
  || die "dolfinx $DOLFINX does not import in the chroot; rebuild with SDM_TRIXIE_REBUILD=1"

# The paper's Fig. 2 run (membrane P1+/P0, midpoint, N = 10, dt = 1e-3, T = 0.8) on 1 and $NP ranks
# in the chroot and on the host (its .venv: dolfinx 0.5.2 on Debian 12), then
# tests/integration/test_versions.py on the host compares the time series (1e-9 relative).
compare_versions() {
  local vdir=output/versions-$DOLFINX np rc=0
  local run=(-m sdm_dolfinx membrane --pair P1+/P0 --scheme midpoint --N 10 --dt 1e-3 --T 0.8
             --write-every 100 --quiet --overwrite)
  [ -x "$SRC/.venv/bin/python" ] || { echo "debian13: no host .venv to compare with: run make setup first" >&2; return 1; }
  rm -rf "${SRC:?}/$vdir"
  mkdir -p "$SRC/$vdir"
  say "the same membrane run on both versions, 1 and $NP ranks -> $vdir"
  for np in 1 "$NP"; do
    in_chroot mpirun -n "$np" python3 "${run[@]}" --out "$vdir/other-np$np" || return 1
    run_bg env -C "$SRC" OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl=self,vader \
      mpirun -n "$np" .venv/bin/python "${run[@]}" --out "$vdir/host-np$np" || return 1
  done
  run_bg env -C "$SRC" SDM_VERSION_RUNS="$vdir" .venv/bin/python -m pytest -q -p no:cacheprovider \
    tests/integration/test_versions.py || rc=$?
  return "$rc"
}

case "$cmd" in
  build) ;;
  shell)   # in the foreground: it owns the terminal
    chroot_env
    chroot "$ROOTFS" /usr/bin/env -i "${CHROOT_ENV[@]}" /bin/sh -c 'cd "$0" && exec bash -i' "$INNER_SRC" ;;
  run) in_chroot "$@" ;;
  versions)
    compare_versions || { say "FAILED: the time series differ between the host's dolfinx and $DOLFINX"; exit 1; }
    say "the membrane time series agree between the host's dolfinx and $DOLFINX (tests/integration/test_versions.py)" ;;
  test)
    rc1=0; rc2=0
    say "pytest on 1 rank ($JOBS workers)${SERIAL_MARK:+, -m '$SERIAL_MARK'}"
    t=$SECONDS
    if [ "$JOBS" -gt 1 ]; then
      in_chroot python3 -m pytest -q -n "$JOBS" --dist loadfile "${SERIAL_ARGS[@]}" tests || rc1=$?
    else
      in_chroot python3 -m pytest -q "${SERIAL_ARGS[@]}" tests || rc1=$?
    fi
    say "1 rank: exit $rc1 in $((SECONDS - t)) s"
    say "pytest on $NP ranks${MPI_MARK:+, -m '$MPI_MARK'}"
    t=$SECONDS
    in_chroot mpirun -n "$NP" python3 -m mpi4py -m pytest -q "${MPI_ARGS[@]}" tests || rc2=$?
    say "$NP ranks: exit $rc2 in $((SECONDS - t)) s"
    [ "$rc1" -eq 0 ] && [ "$rc2" -eq 0 ] || { say "FAILED on dolfinx $DOLFINX (1 rank: $rc1, $NP ranks: $rc2)"; exit 1; }
    say "passed on dolfinx $DOLFINX (1 and $NP ranks)"
    compare_versions || { say "FAILED: the time series differ between the host's dolfinx and $DOLFINX"; exit 1; }
    say "the membrane time series agree between the host's dolfinx and $DOLFINX (tests/integration/test_versions.py)"
    ;;
esac
