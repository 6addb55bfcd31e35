#!/usr/bin/env bash
# Install the Zarco runtime on a Debian-like vessel computer (idempotent: run it
# again to upgrade; an operator's edited configuration and udev rules are kept).
#
#   sudo systemd/install.sh                 # install, enable and start
#   DESTDIR=$PWD/root systemd/install.sh    # into a scratch root (packaging, tests):
#                                           # nothing is started, no root needed
#
# What it does:
#   /opt/zarco                    a venv with the runtime and its runtime dependencies
#                                 only (the simulator, plots and dev tools are extras)
#   zarco user (sysusers.d)       in the dialout group, for the serial ports
#   /var/lib/zarco/recordings     state file and recordings (tmpfiles.d); kept by uninstall
#   /etc/zarco/zarco.toml         the configuration; an existing one is kept and the
#                                 shipped one written beside it as zarco.toml.dist
#   /etc/udev/rules.d/99-zarco.rules   stable device names (an example: edit the
#                                 serial numbers), kept like the configuration
#   /etc/systemd/system/zarco.service  the unit, enabled (started unless DESTDIR)
set -euo pipefail

SRC="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
DESTDIR="${DESTDIR:-}"
PREFIX="${PREFIX:-/opt/zarco}"
PYTHON="${PYTHON:-python3}"
ROOT="${DESTDIR:-/}"
say() { printf 'zarco install: %s\n' "$*"; }

if [[ -z "$DESTDIR" && $EUID -ne 0 ]]; then
    echo "zarco install: run as root (sudo), or with DESTDIR=... for a scratch root" >&2
    exit 2
fi

# keep an operator's edited file: write ours beside it as .dist
install_kept() {  # mode src dst
    local mode="$1" src="$2" dst="$3"
    if [[ -e "$dst" ]] && ! cmp -s "$src" "$dst"; then
        install -D -m "$mode" "$src" "$dst.dist"
        say "kept your $(basename "$dst"); the shipped one is $dst.dist"
    else
        install -D -m "$mode" "$src" "$dst"
    fi
}

# 1. the runtime's venv (runtime dependencies only)
venv="$DESTDIR$PREFIX"
if [[ ! -x "$venv/bin/python" ]]; then
    say "creating the venv $PREFIX"
    "$PYTHON" -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check --upgrade "$SRC"
install -D -m 0644 "$SRC"/docs/*.md -t "$venv/share/doc/zarco/" 2>/dev/null || true
say "runtime installed in $PREFIX ($("$venv/bin/python" -m pip show zarco-runtime | sed -n 's/^Version: //p'))"

# 2. system user, directories (declarative: sysusers.d, tmpfiles.d)
install -D -m 0644 "$SRC/systemd/zarco.sysusers" "$DESTDIR/usr/lib/sysusers.d/zarco.conf"
install -D -m 0644 "$SRC/systemd/zarco.tmpfiles" "$DESTDIR/usr/lib/tmpfiles.d/zarco.conf"
mkdir -p "$DESTDIR/etc"
if command -v systemd-sysusers >/dev/null; then
    systemd-sysusers --root="$ROOT" "$DESTDIR/usr/lib/sysusers.d/zarco.conf"
elif [[ -z "$DESTDIR" ]] && ! id zarco >/dev/null 2>&1; then
    useradd --system --home-dir /var/lib/zarco --shell /usr/sbin/nologin zarco
    usermod -a -G dialout zarco
fi
if command -v systemd-tmpfiles >/dev/null; then
    systemd-tmpfiles --create --root="$ROOT" "$DESTDIR/usr/lib/tmpfiles.d/zarco.conf"
else
    install -d -m 0750 "$DESTDIR/var/lib/zarco/recordings"
fi

# 3. configuration and udev rules (an operator's edits are kept)
install_kept 0644 "$SRC/config/zarco.toml" "$DESTDIR/etc/zarco/zarco.toml"
install_kept 0644 "$SRC/systemd/99-zarco.rules" "$DESTDIR/etc/udev/rules.d/99-zarco.rules"

# 4. the unit
unit="$DESTDIR/etc/systemd/system/zarco.service"
mkdir -p "$(dirname "$unit")"
sed "s#/opt/zarco#$PREFIX#g" "$SRC/systemd/zarco.service" > "$unit.new"
install -D -m 0644 "$unit.new" "$unit"
rm -f "$unit.new"
if [[ -n "$DESTDIR" ]]; then
    systemctl --root="$DESTDIR" enable zarco.service >/dev/null 2>&1 || \
        { mkdir -p "$DESTDIR/etc/systemd/system/multi-user.target.wants"
          ln -sfn /etc/systemd/system/zarco.service \
              "$DESTDIR/etc/systemd/system/multi-user.target.wants/zarco.service"; }
    say "installed into $DESTDIR (not started)"
else
    if command -v udevadm >/dev/null; then udevadm control --reload && udevadm trigger; fi
    systemctl daemon-reload
    systemctl enable zarco.service
    systemctl restart zarco.service
    say "zarco.service enabled and started: journalctl -u zarco -f"
fi
