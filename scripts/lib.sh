# Shared by the scripts: sourced, not run. Gives
#   REPO        the repository's root (the scripts work from any current directory),
#   step NAME   names the step under way; a failing command then says which step failed,
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
