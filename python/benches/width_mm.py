"""Sequential ``width_mm()`` through the package vs a raw Python socket sending the same request
to the same simulator, in one run (issue 13). Prints p50/p90/p99 of each.

    python python/benches/width_mm.py [--calls 20000]

The raw floor is what a hand-written driver does at best: one blocking ``sendall`` of the
pre-encoded frame (encoded by the crate, so the bytes are identical) and ``recv`` until the reply
is complete, with TCP_NODELAY; no checksum check, no parsing beyond the length.
"""

from __future__ import annotations

import argparse
import os
import socket
import statistics
import time

from gripper_rs import _native, wsg


def percentiles(samples_ns: list[int]) -> tuple[float, float, float]:
    q = statistics.quantiles(samples_ns, n=100, method="inclusive")
    return q[49] / 1000, q[89] / 1000, q[98] / 1000


def bench_package(address: str, calls: int) -> list[int]:
    with wsg.Client.connect_tcp(address) as client:
        for _ in range(1000):
            client.width_mm()
        out = []
        clock = time.perf_counter_ns
        for _ in range(calls):
            t = clock()
            client.width_mm()
            out.append(clock() - t)
        return out


def bench_raw(address: str, calls: int) -> list[int]:
    host, port = address.rsplit(":", 1)
    request: bytes = bytes(_native.wsg._width_request())
    with socket.create_connection((host, int(port))) as s:
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

        def query() -> None:
            s.sendall(request)
            buf = b""
            while True:
                buf += s.recv(64)
                # AA AA AA | id | len LE | payload | crc (manual 1.2.1)
                if len(buf) >= 6 and len(buf) >= 8 + int.from_bytes(buf[4:6], "little"):
                    assert buf[3] == 0x43 and buf[6:8] == b"\x00\x00", buf
                    return

        for _ in range(1000):
            query()
        out = []
        clock = time.perf_counter_ns
        for _ in range(calls):
            t = clock()
            query()
            out.append(clock() - t)
        return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--calls", type=int, default=20000)
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds of each")
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()}")
    results: dict[str, list[int]] = {"gripper_rs (package)": [], "raw Python socket": []}
    with wsg.sim.SimServer() as sim:
        for _ in range(args.rounds):
            results["gripper_rs (package)"] += bench_package(sim.address, args.calls)
            results["raw Python socket"] += bench_raw(sim.address, args.calls)
    print(f"load average after: {os.getloadavg()}")
    print(f"{'':20} {'calls':>7} {'p50 µs':>8} {'p90 µs':>8} {'p99 µs':>8}")
    for name, samples in results.items():
        p50, p90, p99 = percentiles(samples)
        print(f"{name:20} {len(samples):7} {p50:8.1f} {p90:8.1f} {p99:8.1f}")


if __name__ == "__main__":
    main()
