#!/usr/bin/env bash
# `make test-trixie`: the whole suite on Debian 13's FEniCSx stack (dolfinx 0.9, PETSc/SLEPc 3.22,
# numpy 2), from a Debian 12 (or any Debian) host, inside a Debian 13 root.
#
#   1. the root: mmdebstrap (debootstrap if mmdebstrap cannot be had) builds a minimal trixie root
#      from Debian's archive into $TRIXIE_ROOT (default /work/trixie-root, outside any git tree);
#      it is kept, so a second run reuses it (and the packages and .venv set up in it);
#   2. the repo: its tracked and untracked-but-not-ignored files are copied to /srv/jointfem in the
#      root (the copy's .venv is kept between runs; the host's .venv is never seen there);
#   3. inside the root, in a private mount namespace (so nothing mounted here shows on the host, and
#      all of it goes when the run ends; a trap unmounts it too): /proc, /sys, /dev/pts, /dev/shm
#      (MPI's shared memory), then `make test` there, which runs tools/setup.sh (it installs
#      the trixie stack) and the whole suite.
#
# Usage: tools/test_trixie.sh [--build-only | --shell | -- COMMAND...]
#   --build-only   build (or check) the root and copy the repo, run nothing inside
#   --shell        an interactive shell in the root, the repo at /srv/jointfem
#   -- COMMAND     run COMMAND in /srv/jointfem inside the root instead of `make test`
# Environment: TRIXIE_ROOT (where the root lives), TRIXIE_MIRROR (default http://deb.debian.org/debian),
#   TRIXIE_NICE (nice level of the run inside, default 10).
set -euo pipefail
REPO="$(cd "$(dirname "$0")/.." && pwd)"
ROOT="${TRIXIE_ROOT:-/work/trixie-root}"
MIRROR="${TRIXIE_MIRROR:-http://deb.debian.org/debian}"
NICE="${TRIXIE_NICE:-10}"
STAMP="$ROOT/.jointfem-trixie-root"
DEST=/srv/jointfem

mode=test
cmd=()
case "${1:-}" in
  "") ;;
  --build-only) mode=build ;;
  --shell) mode=shell ;;
  --) shift; [ $# -gt 0 ] || { echo "test_trixie: -- needs a command" >&2; exit 2; }; mode=cmd; cmd=("$@") ;;
  *) echo "test_trixie: unknown argument '$1' (use --build-only, --shell or -- COMMAND)" >&2; exit 2 ;;
esac

if [ "$(id -u)" -ne 0 ]; then
  echo "test_trixie: building and entering a root (mmdebstrap, chroot, mounts) needs root; run it as root or with sudo" >&2
  exit 2
fi
case "$ROOT" in
  /|"") echo "test_trixie: TRIXIE_ROOT='$ROOT' is not a place for a root" >&2; exit 2 ;;
esac
if git -C "$(dirname "$ROOT")" rev-parse --git-dir >/dev/null 2>&1; then
  echo "test_trixie: TRIXIE_ROOT=$ROOT is inside a git tree; put it outside (default /work/trixie-root)" >&2
  exit 2
fi

t0=$(date +%s)

# ---- 1. the root, built once ------------------------------------------------------------------
build_root() {
  local tmp="$ROOT.partial"
  if ! command -v mmdebstrap >/dev/null && ! command -v debootstrap >/dev/null; then
    echo "test_trixie: installing mmdebstrap on the host"
    apt-get update -q
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q mmdebstrap \
      || DEBIAN_FRONTEND=noninteractive apt-get install -y -q debootstrap
  fi
  rm -rf "$tmp"
  local include=ca-certificates,make,python3,python3-venv,procps
  echo "test_trixie: building the Debian 13 root in $ROOT from $MIRROR (once; a few minutes)"
  if command -v mmdebstrap >/dev/null; then
    mmdebstrap --mode=root --variant=apt --include="$include" --components=main \
      --aptopt='Acquire::Retries "3"' trixie "$tmp" "$MIRROR"
  else
    debootstrap --variant=minbase --include="$include" trixie "$tmp" "$MIRROR"
  fi
  # no services start inside the root when packages are installed there
  printf '#!/bin/sh\nexit 101\n' > "$tmp/usr/sbin/policy-rc.d"
  chmod 755 "$tmp/usr/sbin/policy-rc.d"
  grep -q '^VERSION_CODENAME=trixie' "$tmp/etc/os-release" \
    || { echo "test_trixie: the built root is not trixie:" >&2; cat "$tmp/etc/os-release" >&2; exit 1; }
  printf 'built %s from %s trixie with %s\n' "$(date -u +%FT%TZ)" "$MIRROR" \
    "$(command -v mmdebstrap >/dev/null && echo mmdebstrap || echo debootstrap)" > "$tmp/.jointfem-trixie-root"
  mv "$tmp" "$ROOT"
}

if [ -f "$STAMP" ]; then
  echo "test_trixie: reusing the root in $ROOT ($(cat "$STAMP"))"
else
  [ -e "$ROOT" ] && { echo "test_trixie: $ROOT exists but is no finished root (no $STAMP); remove it first" >&2; exit 1; }
  build_root
fi
t1=$(date +%s)

# The root resolves names and trusts certificates as the host does (pip fetches over https).
cp -L /etc/resolv.conf "$ROOT/etc/resolv.conf"
if compgen -G "/usr/local/share/ca-certificates/*.crt" >/dev/null; then
  mkdir -p "$ROOT/usr/local/share/ca-certificates"
  cp /usr/local/share/ca-certificates/*.crt "$ROOT/usr/local/share/ca-certificates/"
  chroot "$ROOT" update-ca-certificates >/dev/null
fi

# ---- 2. the repo's files, copied (its .venv in the root is kept) -------------------------------
mkdir -p "$ROOT$DEST"
find "$ROOT$DEST" -mindepth 1 -maxdepth 1 ! -name .venv -exec rm -rf {} +
(cd "$REPO" && git ls-files -z -co --exclude-standard | tar --null -T - --ignore-failed-read -cf - 2>/dev/null) \
  | tar -xf - -C "$ROOT$DEST"
echo "test_trixie: copied $(cd "$REPO" && git rev-parse --short HEAD)$(cd "$REPO" && git diff --quiet HEAD || echo '+changes') to $ROOT$DEST"

[ "$mode" = build ] && { echo "test_trixie: root ready in $(( t1 - t0 )) s"; exit 0; }

# ---- 3. run inside, in a private mount namespace ----------------------------------------------
inner=$(cat <<'EOS'
set -euo pipefail
ROOT="$1"; shift
cleanup() {
  for m in dev/shm dev/pts sys proc; do
    mountpoint -q "$ROOT/$m" && umount -l "$ROOT/$m" || true
  done
}
trap cleanup EXIT
mount -t proc proc "$ROOT/proc"
mount -t sysfs sysfs "$ROOT/sys"
mkdir -p "$ROOT/dev/pts" "$ROOT/dev/shm"
mount -t devpts -o newinstance,ptmxmode=0666 devpts "$ROOT/dev/pts"
mount -t tmpfs -o size=4g,mode=1777 shm "$ROOT/dev/shm"
chroot "$ROOT" "$@"
EOS
)
envs=(HOME=/root PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 TERM="${TERM:-dumb}")
for v in OPENBLAS_CORETYPE OPENBLAS_L2_SIZE; do
  [ -n "${!v:-}" ] && envs+=("$v=${!v}")
done
case "$mode" in
  shell) run=(env -i "${envs[@]}" bash -c "cd $DEST && exec bash -i") ;;
  cmd) run=(env -i "${envs[@]}" bash -c "cd $DEST && exec nice -n $NICE \"\$@\"" bash "${cmd[@]}") ;;
  test) run=(env -i "${envs[@]}" bash -c "cd $DEST && exec nice -n $NICE make test") ;;
esac
status=0
unshare --mount --propagation private bash -c "$inner" bash "$ROOT" "${run[@]}" || status=$?
t2=$(date +%s)
echo "test_trixie: root $(( t1 - t0 )) s, run inside $(( t2 - t1 )) s, exit $status"
exit $status
