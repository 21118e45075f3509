#!/bin/sh
# expect_exit.sh CODE REGEX COMMAND [ARGS...]
# Runs COMMAND, passes if it exits with CODE and its stdout+stderr match the
# extended regular expression REGEX (empty REGEX: any output).
code=$1
regex=$2
shift 2
output=$("$@" 2>&1)
status=$?
printf '%s\n' "$output"
if [ "$status" -ne "$code" ]; then
  echo "expect_exit: exit status $status, expected $code" >&2
  exit 1
fi
if [ -n "$regex" ] && ! printf '%s\n' "$output" | grep -Eq -- "$regex"; then
  echo "expect_exit: output does not match /$regex/" >&2
  exit 1
fi
exit 0
