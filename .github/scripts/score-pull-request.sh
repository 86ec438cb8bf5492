#!/usr/bin/env bash
# Score a pull request's new submissions as pending entries of the open round, on this checkout's
# boards, and write the public scores and the board diff as a report (the job summary in GitHub
# Actions, stdout elsewhere). Usage: score-pull-request.sh BASE_REF  (e.g. origin/main)
set -euo pipefail
base=${1:?usage: score-pull-request.sh BASE_REF}
scftc=${SCFTC:-.venv/bin/scftc}
report=${GITHUB_STEP_SUMMARY:-/dev/stdout}
# every path one way, whatever its characters (NUL-separated, never quoted), as `land` lists them
mapfile -d '' -t files < <(git -c core.quotePath=false diff -z --name-only --diff-filter=A "$base"...HEAD -- submissions/)
py=()
for file in "${files[@]}"; do [[ $file == *.py ]] && py+=("$file"); done
{
  echo "## Submissions in this pull request"
  echo
  echo "**Reported by the pull request, not trusted; the seal decides.** (This summary is written by the pull request's own checkout: docs/submitting.md.)"
  echo
  if [ ${#py[@]} -eq 0 ]; then echo "No new file under submissions/."; fi
} >> "$report"
# a pull request may not change a board: the seal workflow is the only writer of leaderboard/
if ! git diff --quiet "$base"...HEAD -- leaderboard/; then
  echo "Rejected: this pull request edits leaderboard/; only the seal workflow writes the boards." >> "$report"
  exit 1
fi
status=0
for file in "${py[@]}"; do
  echo "### \`$file\`" >> "$report"
  if "$scftc" submit "$file" > /tmp/submit.out 2> /tmp/submit.err; then
    { echo '```'; cat /tmp/submit.out; echo '```'; } >> "$report"
  else
    status=1
    { echo "Rejected:"; echo '```'; tail -n 3 /tmp/submit.err; echo '```'; } >> "$report"
  fi
done
{ echo; echo "### Board diff"; echo '```diff'; git diff --stat -- leaderboard/; echo '```'; } >> "$report"
exit $status
