#!/usr/bin/env bash
# Checks softshock's bash completion (packaging/softshock.bash-completion) the way bash calls it:
# COMP_WORDS/COMP_CWORD set, the function that `complete -p softshock` names called directly.
# Usage: check_completion.sh COMPLETION_FILE SOFTSHOCK_EXECUTABLE
# (run by ctest as packaging.completion and by scripts/test-packages on the packaged files)
set -euo pipefail
completion=$1
PATH="$(cd "$(dirname "$2")" && pwd):$PATH"
[ "$(basename "$2")" = softshock ] || { echo "check_completion: $2 is not softshock" >&2; exit 2; }
fail() { echo "check_completion: FAILED: $*" >&2; exit 1; }

# shellcheck source=/dev/null
source "$completion"
spec=$(complete -p softshock) || fail "no completion for softshock after sourcing $completion"
func=$(sed -n 's/.*-F \([^ ]*\) .*/\1/p' <<<"$spec")
[ -n "$func" ] || fail "complete -p softshock names no function: $spec"

# expect 'WORD WORD...' 'CANDIDATE...': completing the last word offers exactly these (sorted).
expect() {
  read -r -a COMP_WORDS <<<"$1"
  [[ $1 == *" " ]] && COMP_WORDS+=("")
  COMP_CWORD=$((${#COMP_WORDS[@]} - 1))
  COMP_LINE=$1
  COMP_POINT=${#1}
  COMPREPLY=()
  set +eu +o pipefail # as in an interactive shell
  "$func" softshock "${COMP_WORDS[COMP_CWORD]}" "${COMP_WORDS[COMP_CWORD - 1]}"
  set -euo pipefail
  local got
  got=$(printf '%s\n' "${COMPREPLY[@]}" | sort | paste -sd ' ')
  [ "$got" = "$2" ] || fail "'$1<TAB>' offers '$got', expected '$2'"
}
expect "softshock su" "submit summary"
expect "softshock --server 127.0.0.1:1 --json wa" "watch"
expect "softshock --ve" "--version"
expect "softshock --token-file " ""
expect "softshock list --for" "--format"
expect "softshock list --format " "csv json table"
expect "softshock fetch abc --file " "h5 spec summary xdmf"
expect "softshock field abc --png " ""
expect "softshock mesh " "delete list upload"
expect "softshock grid re" "reduce"
expect "softshock submit spec.json --w" "--wait"
echo "check_completion: OK ($completion)"
