#!/usr/bin/env python3
"""Writes the seed corpus of fuzz/fuzz_frame.c (fuzz/corpus/), protocol version 3.

Built from docs/protocol.md with Python's struct and zlib, independently of the C codec: one
file per message type, the vector messages (SET_TARGET, PERIOD, TRACE, STATUS) for 1, 2 and 4
interface DoFs, and the inputs a receiver must refuse: truncated, oversized, version-1 and
version-2 frames (a HELLO and an ERROR, as such a peer sends them), a bad checksum, interface-DoF counts of
0 and 5, an unknown type, and two frames back to back.

    python3 fuzz/make_corpus.py        # rewrites fuzz/corpus/
"""
import os
import struct
import zlib

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus")


def frame(typ, seq, payload, version=3):
    body = struct.pack("<BBBBHH", 0x52, 0x54, version, typ, seq, len(payload)) + payload
    return body + struct.pack("<I", zlib.crc32(body) & 0xFFFFFFFF)


def text(s):
    b = s.encode()
    return struct.pack("<B", len(b)) + b


def f64(*v):
    return struct.pack("<%dd" % len(v), *v)


def fourier(base):
    a = [base * (k + 1) - 0.125 * k for k in range(6)]
    b = [0.0] + [-base / (k + 3) for k in range(1, 6)]
    return f64(*a) + f64(*b)


def target(n, h):
    out = struct.pack("<BB", n, h)
    for d in range(n):
        out += f64(*[1e-4 / (k + 1 + d) for k in range(h)]) + f64(*[-2e-5 * (k + 1) for k in range(h)])
    return out


def period(n):
    # version 3: late, clipped-demand and saturated-sensor samples after the samples
    out = struct.pack("<I", 7) + f64(21.819, 10.0, 10.0458) + struct.pack("<IIIIB", 458, 3, 0, 1, n)
    for d in range(n):
        out += fourier(3.4e-4 * (d + 1)) + fourier(-3.3e-4 * (d + 1)) + fourier(0.75 * (d + 1))
    return out


def trace(n, count):
    out = struct.pack("<BB", n, count)
    for i in range(count):
        out += f64(i * 1e-3)
        for d in range(n):
            out += f64(1e-4 * i, -2e-4 * i, 3e-4 * (d + 1), -0.5 * i, 0.01 * i)
    return out


def status(n):
    return (f64(12.5) + struct.pack("<BBB", 0x01, 0, 0) + f64(13.47, 1.0)
            + struct.pack("<QQ", 125000, 3) + f64(2e-4) + struct.pack("<Q", 0)
            + struct.pack("<16Q", *range(16)) + struct.pack("<B", n) + f64(*[0.1 * (d + 1) for d in range(n)])
            + text("" if n == 1 else "demand limit: actuator %d demand -10.4 V, beyond +-10 V" % n))


seeds = {
    "hello": frame(0x01, 1, struct.pack("<H", 3) + text("host")),
    "arm": frame(0x02, 2, b""),
    "disarm": frame(0x03, 3, b""),
    "set_forcing": frame(0x04, 7, f64(13.47, 1.0)),
    "get_status": frame(0x06, 5, b""),
    "get_coeffs": frame(0x07, 6, b""),
    "subscribe": frame(0x08, 8, struct.pack("<BI", 3, 10)),
    "reset_fault": frame(0x09, 9, b""),
    "ping": frame(0x0A, 0x0102, b""),
    "hello_reply": frame(0x81, 1, struct.pack("<HBB", 3, 5, 2) + f64(1e-4, 2.0, 0.0) + text("rths controller")),
    "ack": frame(0x82, 5, struct.pack("<B", 0x05) + f64(12.5)),
    "error": frame(0xFF, 9, struct.pack("<HB", 6, 0x42) + text("no")),
    "unknown_type": frame(0x42, 1, b"abc"),
    # what a receiver refuses
    "bad_version_hello_v1": frame(0x01, 1, struct.pack("<H", 1) + text("host"), version=1),
    "bad_version_error_v1": frame(0xFF, 0, struct.pack("<HB", 3, 0) + text("unsupported protocol version; closing the connection"), version=1),
    "bad_version_hello_v2": frame(0x01, 1, struct.pack("<H", 2) + text("host"), version=2),
    "bad_version_4": frame(0x0A, 1, b"", version=4),
    "oversize": bytes([0x52, 0x54, 0x03, 0x0A, 0, 0, 0x01, 0x10]),
    "bad_dofs_target_0": frame(0x05, 4, struct.pack("<BB", 0, 1) + f64(1e-4, 0.0)),
    "bad_dofs_target_5": frame(0x05, 4, target(5, 1)),
    "bad_dofs_period_5": frame(0x84, 0, period(5)),
    "bad_dofs_trace_0": frame(0x85, 0, struct.pack("<BB", 0, 1) + f64(0.0)),
}
for n in (1, 2, 4):
    seeds["set_target_n%d_h1" % n] = frame(0x05, 3, target(n, 1))
    seeds["set_target_n%d_h5" % n] = frame(0x05, 4, target(n, 5))
    seeds["period_n%d" % n] = frame(0x84, 0, period(n))
    seeds["trace_n%d" % n] = frame(0x85, 0, trace(n, 16 if n < 4 else 3))
    seeds["status_n%d" % n] = frame(0x83, 5, status(n))
seeds["set_target_n1_h0"] = frame(0x05, 2, target(1, 0))
bad = bytearray(seeds["ping"])
bad[-1] ^= 1
seeds["bad_crc"] = bytes(bad)
seeds["truncated"] = seeds["period_n2"][:-7]
seeds["two_frames"] = seeds["set_forcing"] + seeds["set_target_n2_h1"]

os.makedirs(HERE, exist_ok=True)
for old in os.listdir(HERE):
    os.remove(os.path.join(HERE, old))
for name, data in sorted(seeds.items()):
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(data)
print("%d seeds in %s" % (len(seeds), HERE))
