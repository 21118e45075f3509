#!/bin/sh
# expect_caught.sh KIT SHIM CHECK: rbcloth-conformance run against a shim that breaks
# one rule must fail (exit 1) with a "not ok" line for the check of that rule.
# RBC_CONFORMANCE_TIMEOUT (the kit's watchdog) defaults to 120 s here.
kit=$1 shim=$2 want=$3
RBC_CONFORMANCE_TIMEOUT=${RBC_CONFORMANCE_TIMEOUT:-120}
export RBC_CONFORMANCE_TIMEOUT
out=$("$kit" "$shim")
rc=$?
printf '%s\n' "$out" | grep -A2 '^not ok'
if [ "$rc" -ne 1 ]; then
  printf '%s\n' "$out" | tail -n 5
  echo "FAIL: rbcloth-conformance exited $rc on $shim, not 1"
  exit 1
fi
if ! printf '%s\n' "$out" | grep -q "^not ok [0-9]* - $want:"; then
  echo "FAIL: no failed $want check: the kit did not catch this shim's broken rule"
  exit 1
fi
echo "PASS: caught by $want ($(printf '%s\n' "$out" | grep -c '^not ok') failed checks)"
