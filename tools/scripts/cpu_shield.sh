#!/usr/bin/env bash
# A CPU shield without a reboot: the run-time counterpart of `isolcpus=` for a bench or vehicle PC whose kernel
# command line cannot change (docs/daemon.md, "On a vehicle PC: CPU affinity and isolation"). With the cgroup v1
# cpuset controller it moves every task that may move (all but per-CPU kernel threads), the unbound kernel
# workqueues and every interrupt whose affinity may change off the shielded CPUs, and switches off load balancing
# across them. torqued's threads are then pinned there with `realtime.<thread>.cpus`. `off` undoes all of it.
#
#   tools/scripts/cpu_shield.sh on CPUS             e.g. `on 1`: CPU 1 runs only what is pinned there
#   tools/scripts/cpu_shield.sh off
#   tools/scripts/cpu_shield.sh run CPUS -- COMMAND [ARGS...]
#       shield, run COMMAND (its processes may use every CPU: pin its real-time threads into CPUS), undo at exit
#   tools/scripts/cpu_shield.sh status
# Options (before the command; for tests on a fake tree): --cpuset DIR (the cpuset hierarchy's root, default: where
# /proc/mounts has it), --sys DIR (/sys), --proc DIR (/proc), --state FILE (/run/torqued-cpu-shield.state).
#
# Not done by a shield: the timer tick and RCU callbacks still run on the shielded CPUs (that needs `nohz_full=`
# and `rcu_nocbs=` at boot), and "managed" interrupts (a virtio or NVMe queue bound to a CPU by its driver) cannot
# move: they are named. A task's own affinity (taskset, sched_setaffinity) is replaced by its cpuset's when it moves,
# both ways: start what must stay pinned elsewhere after `on`, or pin it again after `off`. On a cgroup v2 system
# with systemd the same is `systemctl set-property --runtime` with `AllowedCPUs=` on init.scope, system.slice and
# user.slice (and the daemon's unit in a slice of its own).
#
# Exit status: 0 done; 1 not possible here (no cpuset hierarchy, not root, a shield already on / none to undo,
# a CPU that is not online); 2 usage error; with `run`, COMMAND's own status.
set -uo pipefail

cpuset_root="" sys=/sys proc=/proc state=/run/torqued-cpu-shield.state
usage() { sed -n '8,14p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
die() { echo "cpu_shield: $*" >&2; exit 1; }

while [[ $# -gt 0 && $1 == --* ]]; do
  [[ $# -ge 2 ]] || usage
  case $1 in
    --cpuset) cpuset_root=$2 ;;
    --sys) sys=$2 ;;
    --proc) proc=$2 ;;
    --state) state=$2 ;;
    *) usage ;;
  esac
  shift 2
done
[[ $# -ge 1 ]] || usage
cmd=$1
shift

# "0-3,6" -> "0 1 2 3 6"; an empty word on a malformed list.
expand_list() {
  local out=() part a b
  IFS=, read -ra parts <<<"$1"
  for part in "${parts[@]}"; do
    if [[ $part =~ ^([0-9]+)-([0-9]+)$ ]]; then
      a=${BASH_REMATCH[1]} b=${BASH_REMATCH[2]}
      ((a <= b)) || { echo ""; return; }
      for ((; a <= b; a++)); do out+=("$a"); done
    elif [[ $part =~ ^[0-9]+$ ]]; then
      out+=("$part")
    else
      echo ""
      return
    fi
  done
  echo "${out[*]}"
}

# "0 2 3" -> the kernel's hex mask with a comma every 32 bits ("d"; "1,00000000" for CPU 32).
hex_mask() {
  local words=() c w i s=""
  for c in $1; do
    w=$((c / 32))
    while ((${#words[@]} <= w)); do words+=(0); done
    words[w]=$((words[w] | (1 << (c % 32))))
  done
  for ((i = ${#words[@]} - 1; i >= 0; i--)); do
    if [[ -z $s ]]; then s=$(printf '%x' "${words[i]}"); else s+=$(printf ',%08x' "${words[i]}"); fi
  done
  echo "${s:-0}"
}

find_cpuset() {
  [[ -n $cpuset_root ]] && return
  cpuset_root=$(awk '$3 == "cgroup" && $4 ~ /(^|,)cpuset(,|$)/ { print $2; exit }' "$proc/mounts")
  [[ -n $cpuset_root ]] || die "no cgroup v1 cpuset hierarchy in $proc/mounts (on cgroup v2 with systemd use \
systemctl set-property --runtime ... AllowedCPUs=, see the comment at the top of this script)"
}

# Move every task listed in the file $1 into the cgroup directory $2; prints "moved stayed".
move_tasks() {
  local moved=0 stayed=0 p list
  list=$(cat "$1")  # a snapshot: the file changes while its tasks leave
  for p in $list; do
    if echo "$p" >>"$2/tasks" 2>/dev/null; then ((moved++)); else ((stayed++)); fi
  done
  echo "$moved $stayed"
}

make_cpuset() {  # DIR CPULIST
  mkdir -p "$1" || die "cannot create $1"
  if ! echo "$2" >"$1/cpuset.cpus" || ! cat "$cpuset_root/cpuset.mems" >"$1/cpuset.mems"; then
    die "cannot set $1/cpuset.cpus to $2"
  fi
}

remove_cpuset() {  # DIR: a cgroup directory goes with rmdir; a fake tree's files are removed first
  [[ -d $1 ]] || return 0
  rmdir "$1" 2>/dev/null && return 0
  rm -f "$1"/tasks "$1"/cpuset.cpus "$1"/cpuset.mems 2>/dev/null
  rmdir "$1" 2>/dev/null || echo "cpu_shield: could not remove $1" >&2
}

shield_on() {
  local shield_list=$1 online shield rest="" c irq moved stayed fixed=0 managed=()
  find_cpuset
  [[ -w $cpuset_root/tasks ]] || die "cannot write $cpuset_root/tasks (run as root)"
  [[ -e $state ]] && die "a shield is already on ($state); run '$0 off' first"
  online=$(expand_list "$(cat "$sys/devices/system/cpu/online")")
  shield=$(expand_list "$shield_list")
  [[ -n $shield ]] || die "CPUS '$shield_list': expected a CPU list such as 1 or 2-3"
  for c in $shield; do [[ " $online " == *" $c "* ]] || die "CPU $c is not online (online: $online)"; done
  for c in $online; do [[ " $shield " == *" $c "* ]] || rest+="${rest:+ }$c"; done
  [[ -n $rest ]] || die "CPUS '$shield_list' are every online CPU: nothing would be left for the rest"
  local rest_list=${rest// /,} wq=$sys/devices/virtual/workqueue/cpumask
  {
    echo "shield=$shield_list"
    echo "load_balance=$(cat "$cpuset_root/cpuset.sched_load_balance" 2>/dev/null || echo 1)"
    [[ -e $wq ]] && echo "wq=$(cat "$wq")"
  } >"$state" || die "cannot write $state"
  make_cpuset "$cpuset_root/torqued_rest" "$rest_list"
  read -r moved stayed < <(move_tasks "$cpuset_root/tasks" "$cpuset_root/torqued_rest")
  echo 0 >"$cpuset_root/cpuset.sched_load_balance" 2>/dev/null
  [[ -e $wq ]] && { hex_mask "$rest" >"$wq" 2>/dev/null || echo "cpu_shield: $wq unchanged" >&2; }
  for irq in "$proc"/irq/[0-9]*; do
    [[ -e $irq/smp_affinity_list ]] || continue
    local was
    was=$(cat "$irq/smp_affinity_list")
    if echo "$rest_list" >"$irq/smp_affinity_list" 2>/dev/null; then
      echo "irq ${irq##*/} $was" >>"$state"
      ((fixed++))
    else
      managed+=("${irq##*/}")
    fi
  done
  echo "cpu_shield: CPU $shield_list shielded; $moved tasks moved to CPU $rest_list, $stayed stay (kernel threads" \
    "that cannot move); $fixed interrupts moved${managed[*]:+, managed (cannot move): ${managed[*]}}"
}

shield_off() {
  local line k v moved stayed wq=$sys/devices/virtual/workqueue/cpumask
  find_cpuset
  [[ -e $state ]] || die "no shield is on (no $state)"
  for d in torqued_run torqued_rest; do
    [[ -e $cpuset_root/$d/tasks ]] || continue
    read -r moved stayed < <(move_tasks "$cpuset_root/$d/tasks" "$cpuset_root")
  done
  while read -r line; do
    k=${line%%=*} v=${line#*=}
    case $line in
      load_balance=*) echo "$v" >"$cpuset_root/cpuset.sched_load_balance" 2>/dev/null ;;
      wq=*) echo "$v" >"$wq" 2>/dev/null ;;
      irq\ *) read -r _ k v <<<"$line"; echo "$v" >"$proc/irq/$k/smp_affinity_list" 2>/dev/null ;;
    esac
  done <"$state"
  remove_cpuset "$cpuset_root/torqued_run"
  remove_cpuset "$cpuset_root/torqued_rest"
  rm -f "$state"
  echo "cpu_shield: off"
}

case $cmd in
  on) [[ $# -eq 1 ]] || usage; shield_on "$1" ;;
  off) [[ $# -eq 0 ]] || usage; shield_off ;;
  status)
    if [[ -e $state ]]; then echo "cpu_shield: on ($(head -1 "$state"))"; else echo "cpu_shield: off"; fi ;;
  run)
    [[ $# -ge 3 && $2 == -- ]] || usage
    shield_on "$1" || exit 1
    trap 'shield_off >/dev/null' EXIT
    trap 'exit 130' INT TERM
    make_cpuset "$cpuset_root/torqued_run" "$(cat "$sys/devices/system/cpu/online")"
    echo $$ >>"$cpuset_root/torqued_run/tasks" || die "cannot enter $cpuset_root/torqued_run"
    shift 2
    "$@"
    exit $? ;;
  *) usage ;;
esac
