#!/usr/bin/env bash
# tools/scripts/cpu_shield.sh on a fake cgroup v1 cpuset tree, /sys and /proc (plain files: nothing on this machine
# changes): `on` moves the tasks, the unbound workqueues' mask and the interrupts off the shielded CPUs and `off`
# restores every value it changed; `run` returns its command's status and leaves no shield; bad CPU lists and a
# second `on` are refused with exit 1, usage errors with 2; the workqueue mask past 32 CPUs has its comma.
set -u
script=$1/tools/scripts/cpu_shield.sh
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0
check() {  # DESCRIPTION EXPECTED ACTUAL
  if [[ "$2" == "$3" ]]; then echo "ok: $1"; else echo "FAIL: $1: expected '$2', got '$3'"; fail=1; fi
}
tree() {  # ONLINE: a fresh fake tree with 3 tasks and 2 interrupts
  rm -rf "$tmp/t"
  mkdir -p "$tmp/t/cg" "$tmp/t/sys/devices/system/cpu" "$tmp/t/sys/devices/virtual/workqueue" \
    "$tmp/t/proc/irq/10" "$tmp/t/proc/irq/11"
  printf '101\n102\n103\n' >"$tmp/t/cg/tasks"
  echo "$1" >"$tmp/t/cg/cpuset.cpus"
  echo 0 >"$tmp/t/cg/cpuset.mems"
  echo 1 >"$tmp/t/cg/cpuset.sched_load_balance"
  echo "$1" >"$tmp/t/sys/devices/system/cpu/online"
  echo "$2" >"$tmp/t/sys/devices/virtual/workqueue/cpumask"
  echo "$1" >"$tmp/t/proc/irq/10/smp_affinity_list"
  echo "$1" >"$tmp/t/proc/irq/11/smp_affinity_list"
}
shield() { "$script" --cpuset "$tmp/t/cg" --sys "$tmp/t/sys" --proc "$tmp/t/proc" --state "$tmp/t/state" "$@"; }

tree 0-3 f
shield on 2-3 >"$tmp/out" 2>&1
check "on: exit 0" 0 $?
check "on: the rest's CPUs" "0,1" "$(cat "$tmp/t/cg/torqued_rest/cpuset.cpus")"
check "on: every task moved" "101 102 103" "$(tr '\n' ' ' <"$tmp/t/cg/torqued_rest/tasks" | sed 's/ $//')"
check "on: workqueue mask" "3" "$(cat "$tmp/t/sys/devices/virtual/workqueue/cpumask")"
check "on: interrupt 10" "0,1" "$(cat "$tmp/t/proc/irq/10/smp_affinity_list")"
check "on: load balancing off" "0" "$(cat "$tmp/t/cg/cpuset.sched_load_balance")"
check "on: its report" "cpu_shield: CPU 2-3 shielded; 3 tasks moved to CPU 0,1, 0 stay (kernel threads that cannot move); 2 interrupts moved" "$(cat "$tmp/out")"
check "status: on" "cpu_shield: on (shield=2-3)" "$(shield status)"
shield on 1 >/dev/null 2>&1
check "a second on: exit 1" 1 $?
shield off >/dev/null
check "off: exit 0" 0 $?
check "off: workqueue mask restored" "f" "$(cat "$tmp/t/sys/devices/virtual/workqueue/cpumask")"
check "off: interrupt 11 restored" "0-3" "$(cat "$tmp/t/proc/irq/11/smp_affinity_list")"
check "off: load balancing restored" "1" "$(cat "$tmp/t/cg/cpuset.sched_load_balance")"
check "off: the rest's cpuset removed" "no" "$([[ -d $tmp/t/cg/torqued_rest ]] && echo yes || echo no)"
check "off: tasks back in the root" "101 102 103 101 102 103" "$(tr '\n' ' ' <"$tmp/t/cg/tasks" | sed 's/ $//')"
check "status: off" "cpu_shield: off" "$(shield status)"
shield off >/dev/null 2>&1
check "off without a shield: exit 1" 1 $?

tree 0-3 f
# shellcheck disable=SC2016  # $0 is the inner shell's
shield run 3 -- sh -c 'cat "$0/t/state" | head -1; exit 7' "$tmp" >"$tmp/out" 2>&1
check "run: the command's status" 7 $?
check "run: the shield was on while it ran" "shield=3" "$(sed -n 2p "$tmp/out")"
check "run: no shield after" "no" "$([[ -e $tmp/t/state || -d $tmp/t/cg/torqued_run ]] && echo yes || echo no)"
check "run: workqueue mask restored" "f" "$(cat "$tmp/t/sys/devices/virtual/workqueue/cpumask")"

tree 0-39 ff,ffffffff
shield on 0 >/dev/null
check "40 CPUs: the mask has its comma" "ff,fffffffe" "$(cat "$tmp/t/sys/devices/virtual/workqueue/cpumask")"
shield off >/dev/null
tree 0-1 3
for bad in 7 0-1 x 3-2; do
  shield on "$bad" >/dev/null 2>&1
  check "on $bad: exit 1" 1 $?
done
check "refused: nothing changed" "0-1" "$(cat "$tmp/t/proc/irq/10/smp_affinity_list")"
shield >/dev/null 2>&1
check "no command: exit 2" 2 $?
shield run 1 ls >/dev/null 2>&1
check "run without --: exit 2" 2 $?
exit $fail
