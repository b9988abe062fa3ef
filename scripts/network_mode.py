#!/usr/bin/python3
"""States and checks the network mode of a ROS graph (the launch files run it).

ROS 1 has no authentication: whoever reaches a node's ports can publish on its topics and
call its XML-RPC API (shutdown, publisherUpdate, ...). roscpp's XML-RPC servers listen on
every interface whatever ROS_HOSTNAME or ROS_IP say, so only a network namespace keeps a
graph on one machine (docs/trust-boundary.md).

    network_mode.py --lab-network false [--launch FILE]   one machine: the graph must run in
        a network namespace with only loopback (scripts/loopback_only roslaunch ddace FILE);
        else exit 1
    network_mode.py --lab-network true    a multi-machine lab: ROS_IP must be a private
        address of an interface of this host and ROS_HOSTNAME unset (or the same); prints
        what is exposed to whom and the firewall rule the lab needs; else exit 1

On success it prints the mode and stays until interrupted (the launch marks it required:
its exit 1 ends the launch before anything drives a robot); --check-only exits 0 instead.
"""
import argparse
import ipaddress
import signal
import socket
import os
import subprocess
import sys


def interfaces():
    return [name for _, name in socket.if_nameindex()]


def addresses():
    """(interface, address) of every address of this host's network namespace."""
    out = subprocess.run(["ip", "-o", "addr", "show"], capture_output=True, text=True).stdout
    found = []
    for line in out.splitlines():
        f = line.split()
        if len(f) >= 4 and f[2] in ("inet", "inet6"):
            found.append((f[1], f[3].split("/")[0]))
    return found


def fail(lines):
    for line in lines:
        print(f"network_mode: {line}", file=sys.stderr)
    return 1


def loopback_mode(launch):
    names = interfaces()
    if names != ["lo"]:
        exposed = [f"{a} on {i}" for i, a in addresses() if not ipaddress.ip_address(a.split("%")[0]).is_loopback]
        return fail([
            f"refused: {launch} runs on one machine (lab_network:=false), but this process is on a network with "
            "more than loopback: interfaces " + ", ".join(names)
            + (" (addresses " + ", ".join(exposed) + ")" if exposed else "") + ";",
            "every roscpp node's XML-RPC port would listen on all of them, reachable from any host on those networks.",
            "Start it in a loopback-only network namespace:",
            f"  scripts/loopback_only roslaunch ddace {launch} ...",
            "or, for a multi-machine lab, ask for it: lab_network:=true with ROS_IP set to this host's lab address.",
        ])
    print("network_mode: one machine: this graph runs in a network namespace with only loopback; "
          "nothing of it is reachable from another host")
    return 0


def lab_mode():
    ip = os.environ.get("ROS_IP", "")
    hostname = os.environ.get("ROS_HOSTNAME", "")
    master = os.environ.get("ROS_MASTER_URI", "")
    if not ip:
        return fail(["lab_network:=true needs ROS_IP: this host's address on the lab's private network "
                     "(export ROS_IP=... before roslaunch, on every machine of the graph)"])
    try:
        address = ipaddress.ip_address(ip)
    except ValueError:
        return fail([f"ROS_IP={ip} is not an IP address"])
    if address.is_loopback or not address.is_private:
        return fail([f"ROS_IP={ip} is {'loopback' if address.is_loopback else 'not a private address'}: "
                     "lab_network:=true needs this host's address on a private lab network "
                     "(10/8, 172.16/12, 192.168/16, fc00::/7)"])
    if hostname and hostname != ip:
        return fail([f"ROS_HOSTNAME={hostname} overrides ROS_IP={ip} for the addresses nodes announce: "
                     "unset ROS_HOSTNAME in lab mode"])
    mine = addresses()
    where = [iface for iface, a in mine if a == ip]
    if not where:
        return fail([f"ROS_IP={ip} is no address of this host (its addresses: "
                     + ", ".join(f"{a} on {i}" for i, a in mine) + ")"])
    # roscpp's XML-RPC binds INADDR_ANY: every IPv4 address (IPv6 too with ROS_IPV6=on).
    families = (4, 6) if os.environ.get("ROS_IPV6") == "on" else (4,)
    others = [f"{a} on {i}" for i, a in mine if a != ip and ipaddress.ip_address(a.split("%")[0]).version in families
              and not ipaddress.ip_address(a.split("%")[0]).is_loopback]
    for line in [
        f"lab network: this graph is reachable from other hosts through {where[0]} ({ip}); master {master}",
        f"exposed: the master, roslaunch and every node's ports (random numbers) on {ip}; roscpp's XML-RPC "
        "ports on every interface of this host" + (" (also " + ", ".join(others) + ")" if others else ""),
        "any host that reaches them can publish on every topic (wheel commands too: the bridge refuses "
        "publishers it does not know, but a caller id can be forged), subscribe, and call any node's API "
        "(shutdown)",
        "the lab's firewall must let only the lab's ROS hosts in, by source (the ports are random), e.g. "
        "nft add rule inet filter input ip saddr != { <ROS host>, ... } tcp dport 1024-65535 ct state new drop "
        "(docs/trust-boundary.md)",
    ]:
        print(f"network_mode: {line}")
    return 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--lab-network", choices=["true", "false"], required=True)
    parser.add_argument("--launch", default="execute_real.launch", help="the launch file, named in the advice")
    parser.add_argument("--check-only", action="store_true", help="exit after the check (0: passed)")
    args, _ = parser.parse_known_args()  # roslaunch appends __name:= and __log:=
    status = lab_mode() if args.lab_network == "true" else loopback_mode(args.launch)
    if status != 0 or args.check_only:
        return status
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    try:
        signal.pause()
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
