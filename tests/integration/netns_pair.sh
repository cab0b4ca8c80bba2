# Sourced by the netns_two_hosts*.sh tests: two network namespaces joined by a veth pair with link-local addresses
# (nothing routable, nothing outside the namespaces).
#   netns_pair NS_A NS_B VETH_A VETH_B PREFIX   -> NS_A has PREFIX.1/24 on VETH_A, NS_B PREFIX.2/24 on VETH_B
netns_pair() {
  local a=$1 b=$2 va=$3 vb=$4 prefix=$5 n
  ip netns add "$a"
  ip netns add "$b"
  ip link add "$va" type veth peer name "$vb"
  ip link set "$va" netns "$a"
  ip link set "$vb" netns "$b"
  ip -n "$a" addr add "$prefix.1/24" dev "$va"
  ip -n "$b" addr add "$prefix.2/24" dev "$vb"
  for n in "$a" "$b"; do ip -n "$n" link set lo up; done
  ip -n "$a" link set "$va" up
  ip -n "$b" link set "$vb" up
}
