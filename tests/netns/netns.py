"""Network namespaces as the hosts of a lab, for multi-host tests (issue 36).

`Lab(["a", "b", "c"])` makes one namespace per host and one more holding a bridge (the lab's
switch, multicast snooping off: a Linux bridge stops forwarding multicast after about five
minutes otherwise). Each host has `lo` and `eth0` on the bridge with 10.231.N.i/24 and a default
route through it (multicast included); no address or route is added outside the namespaces,
and everything is removed on exit, failures and signals included (`with Lab(...) as lab:`).

    lab.run("a", [...])            a process in host a (subprocess.Popen arguments)
    lab.link("b", up=False)        cut b from the switch (ip link set down), and heal it
    lab.blackhole("c", "a")        c's packets to a dropped (a blackhole route)
    lab.slow("c", "1mbit")         c's link slowed both ways (tc tbf)
    lab.drop_multicast("a")        the switch passes no multicast to a

`skip_reason()` says why namespaces cannot be made here (not root, no `ip`), or None.
"""

import atexit
import os
import shutil
import signal
import subprocess
import time

_labs = []


def skip_reason():
    if os.geteuid() != 0:
        return "network namespaces need root"
    for tool in ("ip", "tc"):
        if shutil.which(tool) is None:
            return f"`{tool}` is not installed"
    return None


def _ip(*args, netns=None, check=True):
    command = (["ip", "netns", "exec", netns] if netns else []) + list(args)
    out = subprocess.run(command, capture_output=True, text=True)
    if check and out.returncode != 0:
        raise RuntimeError(f"{' '.join(command)}: {out.stderr.strip()}")
    return out


def poll(condition, deadline_s, every_s=0.1):
    """Calls `condition` until it returns a true value, which it returns; None when the
    (generous) deadline passes first. The tests wait for conditions, never sleep for a result."""
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(every_s)
    return None


class Lab:
    def __init__(self, hosts, subnet=None):
        reason = skip_reason()
        if reason:
            raise RuntimeError(reason)
        self.tag = f"ad{os.getpid() % 100000}"
        # 10.231.N.0/24, N from the pid: two labs of concurrent tests never share addresses.
        self.subnet = subnet if subnet is not None else 10 + os.getpid() % 240
        self.hosts = list(hosts)
        self.switch = f"{self.tag}sw"
        self.made = []
        self.address = {}
        _labs.append(self)

    def ns(self, host):
        return f"{self.tag}{host}"

    def __enter__(self):
        try:
            self._make()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc):
        self.close()

    def _make(self):
        _ip("ip", "netns", "add", self.switch)
        self.made.append(self.switch)
        _ip("ip", "link", "add", "br0", "type", "bridge", "mcast_snooping", "0", netns=self.switch)
        _ip("ip", "link", "set", "br0", "up", netns=self.switch)
        for i, host in enumerate(self.hosts, start=1):
            ns = self.ns(host)
            _ip("ip", "netns", "add", ns)
            self.made.append(ns)
            # Made inside the host's namespace, its peer moved to the switch: nothing is ever
            # created in the namespace the test runs in.
            inner, outer = "eth0", f"p{i}"
            _ip("ip", "link", "add", inner, "type", "veth", "peer", "name", outer, netns=ns)
            _ip("ip", "link", "set", outer, "netns", self.switch, netns=ns)
            _ip("ip", "link", "set", outer, "master", "br0", "up", netns=self.switch)
            address = f"10.231.{self.subnet}.{i}"
            self.address[host] = address
            _ip("ip", "addr", "add", f"{address}/24", "dev", inner, netns=ns)
            _ip("ip", "link", "set", "lo", "up", netns=ns)
            _ip("ip", "link", "set", inner, "up", netns=ns)
            _ip("ip", "route", "add", "default", "dev", inner, netns=ns)

    def close(self):
        for ns in reversed(self.made):
            _ip("ip", "netns", "del", ns, check=False)
        self.made = []
        if self in _labs:
            _labs.remove(self)

    def run(self, host, args, **kwargs):
        return subprocess.Popen(["ip", "netns", "exec", self.ns(host)] + list(args), **kwargs)

    def link(self, host, up):
        i = self.hosts.index(host) + 1
        _ip("ip", "link", "set", f"p{i}", "up" if up else "down", netns=self.switch)

    def blackhole(self, host, to, on=True):
        verb = "add" if on else "del"
        _ip("ip", "route", verb, "blackhole", f"{self.address[to]}/32", netns=self.ns(host))

    def drop_multicast(self, host, on=True):
        """The switch stops passing multicast to `host` (its port's mcast_flood off), as many
        campus and Wi-Fi networks drop multicast. (A blackhole route cannot do it: Linux skips
        the route lookup for multicast sent on a chosen interface, as DDS sends it.)"""
        i = self.hosts.index(host) + 1
        _ip("ip", "link", "set", f"p{i}", "type", "bridge_slave", "mcast_flood",
            "off" if on else "on", netns=self.switch)

    def slow(self, host, rate, on=True):
        """`host`'s link at `rate` (tc's tbf, e.g. "1mbit") both ways: out of its eth0 and out
        of the switch's port towards it."""
        i = self.hosts.index(host) + 1
        for dev, ns in (("eth0", self.ns(host)), (f"p{i}", self.switch)):
            if on:
                _ip("tc", "qdisc", "replace", "dev", dev, "root", "tbf", "rate", rate, "burst",
                    "32kbit", "latency", "400ms", netns=ns)
            else:
                _ip("tc", "qdisc", "del", "dev", dev, "root", netns=ns, check=False)


def _close_all(*_):
    for lab in list(_labs):
        lab.close()


atexit.register(_close_all)
for _sig in (signal.SIGTERM, signal.SIGHUP):
    signal.signal(_sig, lambda sig, frame: (_close_all(), os._exit(128 + sig)))
