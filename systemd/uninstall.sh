#!/usr/bin/env bash
# Remove the Zarco runtime: the unit, the venv and the udev rules if unedited.
# Kept: the recordings and state (/var/lib/zarco), the configuration (/etc/zarco)
# and the zarco user (it owns them).
#
#   sudo systemd/uninstall.sh
#   DESTDIR=$PWD/root systemd/uninstall.sh
set -euo pipefail

SRC="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
DESTDIR="${DESTDIR:-}"
PREFIX="${PREFIX:-/opt/zarco}"
say() { printf 'zarco uninstall: %s\n' "$*"; }

if [[ -z "$DESTDIR" && $EUID -ne 0 ]]; then
    echo "zarco uninstall: run as root (sudo), or with DESTDIR=..." >&2
    exit 2
fi
if [[ -z "$DESTDIR" ]]; then
    systemctl disable --now zarco.service 2>/dev/null || true
else
    systemctl --root="$DESTDIR" disable zarco.service >/dev/null 2>&1 || true
    rm -f "$DESTDIR/etc/systemd/system/multi-user.target.wants/zarco.service"
fi
rm -f "$DESTDIR/etc/systemd/system/zarco.service"
rules="$DESTDIR/etc/udev/rules.d/99-zarco.rules"
if [[ -e "$rules" ]] && cmp -s "$rules" "$SRC/systemd/99-zarco.rules"; then
    rm -f "$rules"
elif [[ -e "$rules" ]]; then
    say "kept your edited $rules"
fi
rm -f "$rules.dist"
rm -rf "$DESTDIR$PREFIX"
rm -f "$DESTDIR/usr/lib/tmpfiles.d/zarco.conf"
[[ -z "$DESTDIR" ]] && systemctl daemon-reload 2>/dev/null || true
say "removed; kept $DESTDIR/var/lib/zarco (recordings, state) and $DESTDIR/etc/zarco"
