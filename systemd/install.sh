#!/usr/bin/env bash
# Install the Zarco runtime on a Debian-like vessel computer (idempotent: run it
# again to upgrade; an operator's edited configuration and udev rules are kept).
#
#   sudo systemd/install.sh                     # install, enable, (re)start when idle
#   sudo systemd/install.sh --wait              # the boat is under way: wait until idle
#   sudo systemd/install.sh --force             # restart even under way (ends the mission)
#   sudo systemd/install.sh --wheelhouse DIR    # offline: the locked wheels from DIR
#   DESTDIR=$PWD/root systemd/install.sh        # into a scratch root (packaging, tests):
#                                               # nothing is started, no root needed
#
# Before it changes anything it asks the running runtime whether the boat is under
# way (its control socket's status; without an answer, its state file): under way,
# or when it cannot tell, it stops there (exit 3) unless --wait or --force.  It asks
# again just before the restart.
#
# What it does:
#   /opt/zarco                    a venv with the runtime and its runtime dependencies
#                                 only, each at the version and sha256 of
#                                 systemd/requirements.lock (pip --require-hashes; the
#                                 runtime itself is built from this checkout, offline)
#   zarco user (sysusers.d)       in the dialout group, for the serial ports
#   /var/lib/zarco/recordings     state file and recordings (tmpfiles.d); kept by uninstall
#   /etc/zarco/zarco.toml         the configuration, 0640 root:zarco; an existing one is
#                                 kept (its mode set so) and the shipped one written
#                                 beside it as zarco.toml.dist
#   /etc/zarco/shore-users        the shore link's users file ([shore] users_file), made
#                                 empty, 0600 zarco, if absent
#   /etc/udev/rules.d/99-zarco.rules   stable device names (an example: edit the
#                                 serial numbers), kept like the configuration
#   /etc/systemd/system/zarco.service  the unit, its DeviceAllow= generated from the
#                                 configuration's ports, enabled (started unless DESTDIR)
#
# Exit: 0 done; 2 refused (usage, configuration); 3 not done: the boat is under way.
set -euo pipefail

SRC="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
DESTDIR="${DESTDIR:-}"
PREFIX="${PREFIX:-/opt/zarco}"
PYTHON="${PYTHON:-python3}"
ROOT="${DESTDIR:-/}"
LOCK="$SRC/systemd/requirements.lock"
say() { printf 'zarco install: %s\n' "$*"; }
die() { printf 'zarco install: %s\n' "$1" >&2; exit "${2:-2}"; }

force=0 wait=0 wheelhouse=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --force) force=1 ;;
        --wait) wait=1 ;;
        --wheelhouse) [[ $# -ge 2 ]] || die "--wheelhouse needs a directory"
                      wheelhouse="$2"; shift ;;
        --wheelhouse=*) wheelhouse="${1#*=}" ;;
        -h|--help) sed -n '2,34p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) die "unknown argument $1 (--force, --wait, --wheelhouse DIR)" ;;
    esac
    shift
done
if [[ -z "$DESTDIR" && $EUID -ne 0 ]]; then
    die "run as root (sudo), or with DESTDIR=... for a scratch root"
fi
[[ -z "$wheelhouse" || -d "$wheelhouse" ]] || die "--wheelhouse $wheelhouse: no such directory"
[[ -r "$LOCK" ]] || die "$LOCK: missing (make lock)"

cfg="$DESTDIR/etc/zarco/zarco.toml"
# the system's Python runs the state check (standard library only), before anything
# of the new version is installed
helper() { (cd "$SRC" && "$PYTHON" -m zarco_runtime.install "$@"); }

# under way? 0: no (idle, not running); 3: yes; 4: cannot tell.  Prints why.
runtime_state() {
    local active=""
    if [[ -z "$DESTDIR" ]] && systemctl is-active --quiet zarco.service 2>/dev/null; then
        active="--active"
    fi
    helper state --config "$cfg" $active
}

# 0 when the runtime may be stopped now (idle, not running, or --force)
may_stop() {
    local why rc
    while true; do
        rc=0
        why="$(runtime_state)" || rc=$?
        if [[ $rc -eq 0 ]]; then
            say "$why"
            return 0
        fi
        if [[ $force -eq 1 ]]; then
            say "$why: --force, going on"
            return 0
        fi
        if [[ $wait -eq 0 ]]; then
            say "$why"
            return 3
        fi
        say "$why: waiting until it is idle (Ctrl-C to give up)"
        sleep 10
    done
}

if ! may_stop; then
    die "nothing changed: run it again when the boat is idle, with --wait to wait for \
that, or --force to restart it now (that ends the mission)" 3
fi

# 1. the runtime's venv: its locked dependencies (hashes checked), then the runtime
#    itself from this checkout, without the network
venv="$DESTDIR$PREFIX"
if [[ ! -x "$venv/bin/python" ]]; then
    say "creating the venv $PREFIX"
    "$PYTHON" -m venv "$venv"
fi
pip=("$venv/bin/python" -m pip --quiet --disable-pip-version-check)
if [[ -n "$wheelhouse" ]]; then
    "${pip[@]}" install --require-hashes --no-index --find-links "$wheelhouse" -r "$LOCK"
else
    "${pip[@]}" install --require-hashes -r "$LOCK"
fi
"${pip[@]}" install --no-deps --no-build-isolation --no-index "$SRC"
install -D -m 0644 "$SRC"/docs/*.md -t "$venv/share/doc/zarco/" 2>/dev/null || true
say "runtime installed in $PREFIX ($("$venv/bin/python" -m pip show zarco-runtime \
    | sed -n 's/^Version: //p'); dependencies as locked in systemd/requirements.lock)"

# the unit for the configuration that will be in place (an operator's, or the shipped
# one), by the new runtime's own loader: a configuration it refuses stops the install
effective="$cfg"
[[ -e "$cfg" ]] || effective="$SRC/config/zarco.toml"
notes="$(mktemp)"
trap 'rm -f "$notes"' EXIT
unit_text="$("$venv/bin/python" -m zarco_runtime.install unit --config "$effective" \
    --template "$SRC/systemd/zarco.service" --prefix "$PREFIX" \
    --source /etc/zarco/zarco.toml 2>"$notes")" || \
    die "$(cat "$notes") (fix it, then run the install again)" 2
while IFS= read -r line; do say "device $line"; done < "$notes"

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
# the zarco user and group by number, from the (scratch) root's own databases
uid="$(awk -F: '$1 == "zarco" { print $3 }' "$ROOT/etc/passwd")"
gid="$(awk -F: '$1 == "zarco" { print $3 }' "$ROOT/etc/group")"
[[ -n "$uid" && -n "$gid" ]] || die "no zarco user in $ROOT/etc/passwd"

# mode and owner of a file (ownership only as root: a scratch root needs none)
set_mode() {  # mode uid:gid path
    [[ $EUID -eq 0 ]] && chown "$2" "$3"
    chmod "$1" "$3"
}

# keep an operator's edited file: write ours beside it as .dist; either way the file
# ends with the mode and owner given
install_kept() {  # mode uid:gid src dst
    local mode="$1" owner="$2" src="$3" dst="$4" was
    if [[ -e "$dst" ]] && ! cmp -s "$src" "$dst"; then
        install -D -m "$mode" "$src" "$dst.dist"
        set_mode "$mode" "$owner" "$dst.dist"
        say "kept your $(basename "$dst"); the shipped one is $dst.dist"
        was="$(stat -c '%a %u:%g' "$dst")"
        set_mode "$mode" "$owner" "$dst"
        if [[ "$(stat -c '%a %u:%g' "$dst")" != "$was" ]]; then
            say "$dst: now mode $(stat -c '%a, owner %u:%g' "$dst") (was $was)"
        fi
    else
        install -D -m "$mode" "$src" "$dst"
        set_mode "$mode" "$owner" "$dst"
    fi
}

# 3. configuration (readable by the runtime's group only: it names the users file
#    and the keys), the shore users file, udev rules (an operator's edits are kept)
install_kept 0640 "0:$gid" "$SRC/config/zarco.toml" "$cfg"
users="$(helper users-file --config "$cfg")"
if [[ ! -e "$DESTDIR$users" ]]; then
    install -d -m 0755 "$(dirname "$DESTDIR$users")"
    ( umask 077
      printf '%s\n' "# zarco shore link users ([shore] auth = \"usrpwd\"): one user:password" \
          "# a line; give each a role in [shore] operators or viewers" > "$DESTDIR$users" )
    set_mode 0600 "$uid:$gid" "$DESTDIR$users"
    say "made $users (empty, mode 600, owner zarco): add user:password lines"
fi
install_kept 0644 "0:0" "$SRC/systemd/99-zarco.rules" "$DESTDIR/etc/udev/rules.d/99-zarco.rules"

# 4. the unit
unit="$DESTDIR/etc/systemd/system/zarco.service"
mkdir -p "$(dirname "$unit")"
printf '%s\n' "$unit_text" > "$unit.new"
install -D -m 0644 "$unit.new" "$unit"
rm -f "$unit.new"
if [[ -n "$DESTDIR" ]]; then
    systemctl --root="$DESTDIR" enable zarco.service >/dev/null 2>&1 || \
        { mkdir -p "$DESTDIR/etc/systemd/system/multi-user.target.wants"
          ln -sfn /etc/systemd/system/zarco.service \
              "$DESTDIR/etc/systemd/system/multi-user.target.wants/zarco.service"; }
    say "installed into $DESTDIR (not started)"
    exit 0
fi
if command -v udevadm >/dev/null; then udevadm control --reload && udevadm trigger; fi
systemctl daemon-reload
systemctl enable zarco.service
# the boat may have got under way while installing: ask again
if ! may_stop; then
    die "installed but NOT restarted: the running runtime is the old one until \
'systemctl restart zarco' when the boat is idle (or run the install again with --wait)" 3
fi
systemctl restart zarco.service
say "zarco.service enabled and started: journalctl -u zarco -f"
