#!/bin/sh
# Every design (configs.sh) with gc+lqr and gc+lqr+dob (the lab's Kdist 0.2) through the
# emulated buses, lock-step: stand 10 s, push, the slow and the dynamic walk, the step onto the
# object. Run dirs under OUT (default runs/); table.py OUT prints the report's table.
# Usage: sh configs.sh && sh runs.sh [OUT]
OUT=${1:-runs}
for design in ours paper lab closed-chain; do
  for controller in gc+lqr gc+lqr+dob; do
    for experiment in stand push walk-slow walk-dynamic step-on-object; do
      duration=""
      [ "$experiment" = stand ] && duration="--duration 10"
      kdist=""  # (--kdist is refused for a controller without a DOB)
      [ "$controller" = gc+lqr+dob ] && kdist="--kdist 0.2"
      hil run "$experiment" --config "$design.toml" --emulate --controller "$controller" \
        $kdist $duration --no-plots --no-mcap --json --out "$OUT/$design" > /dev/null
    done
  done
done
