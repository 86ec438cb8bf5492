#!/usr/bin/env bash
# Score a pull request's new submissions as pending entries of the open round, on this checkout's
# boards, and write the public scores and the board diff as a report (the job summary in GitHub
# Actions, stdout elsewhere). Usage: score-pull-request.sh BASE_REF  (e.g. origin/main)
set -euo pipefail
base=${1:?usage: score-pull-request.sh BASE_REF}
scftc=${SCFTC:-.venv/bin/scftc}
report=${GITHUB_STEP_SUMMARY:-/dev/stdout}
mapfile -t files < <(git diff --name-only --diff-filter=A "$base"...HEAD -- submissions/ | grep '\.py$' || true)
{
  echo "## Submissions in this pull request"
  echo
  if [ ${#files[@]} -eq 0 ]; then echo "No new file under submissions/."; fi
} >> "$report"
# a board the pull request edits may only add pending entries to the base's
for board in leaderboard/*.json; do
  if ! git diff --quiet "$base"...HEAD -- "$board"; then
    version=$(basename "$board" .json)
    git show "$base:$board" > "/tmp/base-$version.json"
    "$scftc" leaderboard verify --benchmark "$version" --base "/tmp/base-$version.json"
    git checkout "$base" -- "$board"  # score on the base's board: the runner decides the numbers
  fi
done
status=0
for file in "${files[@]}"; do
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
