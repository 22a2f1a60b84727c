# Shared by the scripts: sourced, not run. Gives
#   REPO        the repository's root (the scripts work from any current directory),
#   step NAME   names the step under way; a failing command then says which step failed,
#   have_pkg P  whether the Debian package P is installed,
#   apt_install WHY P...  installs packages, or without root and sudo says what is missing,
#   bin NAME    the path of a release binary, wherever cargo puts its target directory
#               (CARGO_TARGET_DIR, .cargo/config.toml, or the default target/).
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SCRIPT="$(basename "$0")"
STEP="start"
step() { STEP="$*"; echo "== $*"; }
trap 'rc=$?; echo "$SCRIPT: FAILED during \"$STEP\" (exit $rc)" >&2' ERR

target_dir() {
    local meta
    meta="$(cd "$REPO" && cargo metadata --format-version 1 --no-deps 2>/dev/null)" || {
        echo "$SCRIPT: cargo metadata failed in $REPO: is cargo installed and the workspace intact?" >&2
        return 1
    }
    printf '%s' "$meta" | grep -o '"target_directory":"[^"]*"' | head -1 | cut -d'"' -f4
}

# The target folder of the aarch64 builds: $SCANNER_CROSS_TARGET_DIR when set (CI keeps one between
# its runs on a machine, so that a warm run rebuilds only what changed), else the workspace's.
cross_target_dir() {
    if [ -n "${SCANNER_CROSS_TARGET_DIR:-}" ]; then
        mkdir -p "$SCANNER_CROSS_TARGET_DIR" && printf '%s' "$SCANNER_CROSS_TARGET_DIR"
    else
        target_dir
    fi
}

bin() {
    local dir
    dir="$(target_dir)"
    [ -n "$dir" ] || { echo "$SCRIPT: could not find cargo's target directory" >&2; return 1; }
    if [ ! -x "$dir/release/$1" ]; then
        echo "$SCRIPT: $dir/release/$1 is missing: build it with cargo build --release -p ${2:-$1}" >&2
        return 1
    fi
    printf '%s' "$dir/release/$1"
}

have_pkg() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }

# apt_install WHY PACKAGE...: installs, or without root and sudo says what is missing and how.
apt_install() {
    local why="$1"
    shift
    local sudo=""
    if [ "$(id -u)" -ne 0 ]; then
        if command -v sudo >/dev/null && sudo -n true 2>/dev/null; then
            sudo="sudo"
        elif command -v sudo >/dev/null && [ -t 0 ] && [ -z "${CI:-}" ]; then
            # A terminal: ask for the password rather than refuse.
            echo "setup: installing $* ($why): sudo may ask for your password" >&2
            if sudo -v; then
                sudo="sudo"
            else
                echo "setup: sudo was refused; install them yourself with:" >&2
                echo "    sudo apt-get update && sudo apt-get install -y $*" >&2
                return 1
            fi
        else
            echo "setup: missing system package(s): $* ($why)." >&2
            echo "setup: this user is not root and sudo cannot ask here (no terminal); run:" >&2
            echo "    sudo apt-get update && sudo apt-get install -y $*" >&2
            return 1
        fi
    fi
    if [ -z "${SCANNER_APT_UPDATED:-}" ]; then
        $sudo apt-get update -qq
        export SCANNER_APT_UPDATED=1
    fi
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "$@"
}
