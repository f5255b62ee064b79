#!/usr/bin/env python3
"""Writes small ROS 2 bags with known contents for io_ros2_bag_test.

The writer follows the published formats (rosbag2 sqlite3 schema, the MCAP specification, OMG CDR
as used by ROS 2, ROS 1 serialisation, the Zstandard and LZ4 frame formats) and shares no code with
the C++ readers it tests. Standard library only: zstd frames are written with raw and RLE blocks, LZ4
frames with a small greedy block compressor, so no compression tool is needed.

Usage: make_ros2_fixtures.py OUT_DIR. Writes into OUT_DIR:
  ros2_db3/            metadata.yaml + two split .db3 files (rows out of time order, times interleaved)
  ros2_db3_msgzstd/    one .db3 whose message blobs are zstd frames (compression_mode MESSAGE)
  ros2_db3_filezstd/   one .db3.zstd (compression_mode FILE)
  ros2_mcap/           metadata.yaml + ros2.mcap (storage_identifier mcap)
  ros2.mcap            chunks "", zstd and lz4, a message outside chunks, attachment, metadata,
                       a json channel, a ros1 channel, summary section and footer
  small.mcap           an uncompressed chunk, an lz4 chunk and a top-level message, for truncation loops
  bad_crc.mcap         small.mcap with one byte of its chunk changed (CRC left as written)
  fixtures.json        byte offsets the test checks error messages against

Message contents (the test recomputes them from the same formulas):
  cloud k (k = 0..3), point i (i = 0..9): x = k + i/2, y = -i/4, z = 1 + i/8, intensity = 3i,
    ring = i % 16, time = i/1024 [s]; point 3 of every cloud has x = NaN.
    header stamp = (1700000000 + k) s + (1000k + 500) ns, frame "lidar", log time = stamp + 1 ms.
  /points_be: one big-endian CDR cloud, big-endian point data, x/y/z FLOAT64, intensity UINT8,
    ring UINT8, t UINT32 [ns] = 1000 i; same x/y/z/intensity formulas with k = 7; 6 points, none NaN.
  /points_abs: one cloud with x/y/z FLOAT32 and timestamp FLOAT64 absolute [s] = stamp + i/256;
    k = 5, 4 points, no ring, no intensity.
  imu k (k = 0..4): orientation (x, y, z, w) = (k/8, -k/16, 1/4, 1), covariances c[j] = k + j/4,
    angular velocity (k/4, -k/2, 1 + k), linear acceleration (0.5, -0.25, 9.8125 + k/16),
    stamp = (1700000000 + k) s + 250000000 ns, frame "imu", log time = stamp + 2 ms.
  scan k (k = 0..1): 3 packets, packet p stamp = (1700000100 + k) s + 1000 p ns, data[j] =
    (7k + 3p + j) & 0xff for j < 1204, data[100:600] = 0, data[1204] = 0x37, data[1205] = 0x22;
    header stamp = (1700000100 + k) s, frame "velodyne", log time = stamp + 5 ms.
"""

import json
import math
import os
import shutil
import sqlite3
import struct
import sys
import zlib

M32 = 0xFFFFFFFF

# ---------------------------------------------------------------- CDR (XCDR1, ROS 2)


class Cdr:
    """CDR body writer; alignment is relative to the byte after the 4-byte encapsulation header."""

    def __init__(self, big_endian=False):
        self.e = ">" if big_endian else "<"
        self.big = big_endian
        self.b = bytearray()

    def align(self, n):
        while len(self.b) % n:
            self.b.append(0)

    def put(self, fmt, *v):
        size = struct.calcsize("<" + fmt)
        self.align(size)
        self.b += struct.pack(self.e + fmt, *v)

    def u8(self, v): self.put("B", v)
    def u32(self, v): self.put("I", v)
    def i32(self, v): self.put("i", v)
    def f64(self, v): self.put("d", v)

    def string(self, s):
        raw = s.encode() + b"\0"
        self.u32(len(raw))
        self.b += raw

    def raw(self, data):
        self.b += data

    def message(self):
        return (b"\x00\x00" if self.big else b"\x00\x01") + b"\x00\x00" + bytes(self.b)


def header(c, sec, nsec, frame):
    c.i32(sec)
    c.u32(nsec)
    c.string(frame)


FLOAT32, FLOAT64, UINT8, UINT16, UINT32 = 7, 8, 2, 4, 6
FMT = {FLOAT32: "f", FLOAT64: "d", UINT8: "B", UINT16: "H", UINT32: "I"}


def point_cloud2(sec, nsec, frame, fields, point_step, points, cdr_big=False, data_big=False):
    """fields: [(name, offset, datatype)]; points: list of dicts name -> value."""
    e = ">" if data_big else "<"
    data = bytearray()
    for p in points:
        rec = bytearray(point_step)
        for name, off, dt in fields:
            struct.pack_into(e + FMT[dt], rec, off, p[name])
        data += rec
    c = Cdr(cdr_big)
    header(c, sec, nsec, frame)
    cloud_body(c, len(points), fields, point_step, data, data_big)
    return c.message()


def cloud_body(c, width, fields, point_step, data, data_big=False, is_dense=False):
    """A PointCloud2 after its header: one row of `width` points laid out by `fields`, then `data`."""
    c.u32(1)  # height
    c.u32(width)
    c.u32(len(fields))
    for name, off, dt in fields:
        c.string(name)
        c.u32(off)
        c.u8(dt)
        c.u32(1)
    c.u8(1 if data_big else 0)
    c.u32(point_step)
    c.u32(point_step * width)
    c.u32(len(data))
    c.raw(bytes(data))
    c.u8(1 if is_dense else 0)


def cloud_stamp(k):
    return 1700000000 + k, 1000 * k + 500


def make_cloud(k):
    fields = [("x", 0, FLOAT32), ("y", 4, FLOAT32), ("z", 8, FLOAT32), ("intensity", 12, FLOAT32),
              ("ring", 16, UINT16), ("time", 20, FLOAT32)]
    pts = []
    for i in range(10):
        pts.append({"x": math.nan if i == 3 else k + i / 2, "y": -i / 4, "z": 1 + i / 8,
                    "intensity": 3.0 * i, "ring": i % 16, "time": i / 1024})
    sec, nsec = cloud_stamp(k)
    return point_cloud2(sec, nsec, "lidar", fields, 24, pts)


def make_cloud_be():
    k = 7
    fields = [("x", 0, FLOAT64), ("y", 8, FLOAT64), ("z", 16, FLOAT64), ("intensity", 24, UINT8),
              ("ring", 25, UINT8), ("t", 28, UINT32)]
    pts = [{"x": k + i / 2, "y": -i / 4, "z": 1 + i / 8, "intensity": 3 * i, "ring": i % 16,
            "t": 1000 * i} for i in range(6)]
    sec, nsec = cloud_stamp(k)
    return point_cloud2(sec, nsec, "lidar", fields, 32, pts, cdr_big=True, data_big=True)


def make_cloud_abs():
    k = 5
    sec, nsec = cloud_stamp(k)
    fields = [("x", 0, FLOAT32), ("y", 4, FLOAT32), ("z", 8, FLOAT32), ("timestamp", 16, FLOAT64)]
    pts = [{"x": k + i / 2, "y": -i / 4, "z": 1 + i / 8, "timestamp": sec + nsec * 1e-9 + i / 256}
           for i in range(4)]
    return point_cloud2(sec, nsec, "lidar", fields, 24, pts)


def imu_values(k):
    cov = [k + j / 4 for j in range(9)]
    return dict(q=(k / 8, -k / 16, 0.25, 1.0), cov=cov, w=(k / 4, -k / 2, 1.0 + k),
                a=(0.5, -0.25, 9.8125 + k / 16), sec=1700000000 + k, nsec=250000000)


def make_imu(k):
    v = imu_values(k)
    c = Cdr()
    header(c, v["sec"], v["nsec"], "imu")
    # orientation, angular velocity and linear acceleration, each followed by its covariance
    for field in ("q", "cov", "w", "cov", "a", "cov"):
        for x in v[field]:
            c.f64(x)
    return c.message()


def make_imu_ros1(k):
    """sensor_msgs/Imu in ROS 1 serialisation: little endian, packed, strings without NUL."""
    v = imu_values(k)
    b = struct.pack("<III", 42, v["sec"], v["nsec"]) + struct.pack("<I", 3) + b"imu"
    b += struct.pack("<4d", *v["q"]) + struct.pack("<9d", *v["cov"])
    b += struct.pack("<3d", *v["w"]) + struct.pack("<9d", *v["cov"])
    b += struct.pack("<3d", *v["a"]) + struct.pack("<9d", *v["cov"])
    return b


def packet_bytes(k, p):
    d = bytearray((7 * k + 3 * p + j) & 0xFF for j in range(1206))
    d[100:600] = bytes(500)
    d[1204] = 0x37
    d[1205] = 0x22
    return bytes(d)


def make_scan(k):
    c = Cdr()
    header(c, 1700000100 + k, 0, "velodyne")
    c.u32(3)
    for p in range(3):
        c.i32(1700000100 + k)
        c.u32(1000 * p)
        c.raw(packet_bytes(k, p))
    return c.message()


def stamp_ns(sec, nsec):
    return sec * 1000000000 + nsec


PC2, IMU, SCAN = "sensor_msgs/msg/PointCloud2", "sensor_msgs/msg/Imu", "velodyne_msgs/msg/VelodyneScan"


def all_messages():
    """(topic, type, log_time_ns, cdr bytes) for every fixture message."""
    out = []
    for k in range(4):
        out.append(("/points", PC2, stamp_ns(*cloud_stamp(k)) + 1000000, make_cloud(k)))
    for k in range(5):
        v = imu_values(k)
        out.append(("/imu", IMU, stamp_ns(v["sec"], v["nsec"]) + 2000000, make_imu(k)))
    for k in range(2):
        out.append(("/velodyne_packets", SCAN, stamp_ns(1700000100 + k, 0) + 5000000, make_scan(k)))
    out.append(("/points_be", PC2, stamp_ns(*cloud_stamp(7)) + 1000000, make_cloud_be()))
    out.append(("/points_abs", PC2, stamp_ns(*cloud_stamp(5)) + 1000000, make_cloud_abs()))
    return out

# ---------------------------------------------------------------- xxHash32, zstd and LZ4 frames


def rotl(x, r):
    return ((x << r) | (x >> (32 - r))) & M32


def xxh32(data, seed=0):
    p1, p2, p3, p4, p5 = 2654435761, 2246822519, 3266489917, 668265263, 374761393
    n, i = len(data), 0
    if n >= 16:
        v = [(seed + p1 + p2) & M32, (seed + p2) & M32, seed & M32, (seed - p1) & M32]
        while i + 16 <= n:
            for lane in range(4):
                x = struct.unpack_from("<I", data, i + 4 * lane)[0]
                v[lane] = (rotl((v[lane] + x * p2) & M32, 13) * p1) & M32
            i += 16
        h = (rotl(v[0], 1) + rotl(v[1], 7) + rotl(v[2], 12) + rotl(v[3], 18)) & M32
    else:
        h = (seed + p5) & M32
    h = (h + n) & M32
    while i + 4 <= n:
        h = (rotl((h + struct.unpack_from("<I", data, i)[0] * p3) & M32, 17) * p4) & M32
        i += 4
    while i < n:
        h = (rotl((h + data[i] * p5) & M32, 11) * p1) & M32
        i += 1
    h ^= h >> 15
    h = (h * p2) & M32
    h ^= h >> 13
    h = (h * p3) & M32
    h ^= h >> 16
    return h


def zstd_frame(data):
    """One zstd frame of raw and RLE blocks (RFC 8878): single segment, 4-byte content size."""
    out = bytearray(struct.pack("<I", 0xFD2FB528))
    out.append(0xA0)  # Frame_Content_Size_flag 2 (4 bytes), Single_Segment_flag
    out += struct.pack("<I", len(data))
    blocks = []
    i, n = 0, len(data)
    raw_start = 0
    while i < n:
        j = i
        while j < n and data[j] == data[i] and j - i < 131072:
            j += 1
        if j - i >= 64:
            if raw_start < i:
                blocks.append(("raw", data[raw_start:i]))
            blocks.append(("rle", data[i], j - i))
            raw_start = j
        i = j if j - i >= 64 else i + 1
    if raw_start < n:
        blocks.append(("raw", data[raw_start:n]))
    split = []
    for b in blocks:  # raw blocks hold at most 128 KiB
        if b[0] == "raw":
            for s in range(0, len(b[1]), 131072):
                split.append(("raw", b[1][s:s + 131072]))
        else:
            split.append(b)
    if not split:
        split = [("raw", b"")]
    for idx, b in enumerate(split):
        last = 1 if idx == len(split) - 1 else 0
        if b[0] == "raw":
            out += (last | (0 << 1) | (len(b[1]) << 3)).to_bytes(3, "little") + bytes(b[1])
        else:
            out += (last | (1 << 1) | (b[2] << 3)).to_bytes(3, "little") + bytes([b[1]])
    return bytes(out)


def lz4_block(src):
    """LZ4 block format with greedy matching; honours the end-of-block rules (last 5 bytes literal,
    last match starting at least 12 bytes before the end)."""
    n = len(src)
    out = bytearray()
    table = {}
    anchor = i = 0

    def length_bytes(v):
        b = bytearray()
        while v >= 255:
            b.append(255)
            v -= 255
        b.append(v)
        return b

    while i + 12 <= n:
        key = src[i:i + 4]
        cand = table.get(key)
        table[key] = i
        if cand is not None and i - cand <= 65535:
            m = 4
            while i + m < n - 5 and src[cand + m] == src[i + m]:
                m += 1
            lit = src[anchor:i]
            tok_l = min(len(lit), 15)
            tok_m = min(m - 4, 15)
            out.append((tok_l << 4) | tok_m)
            if len(lit) >= 15:
                out += length_bytes(len(lit) - 15)
            out += lit
            out += struct.pack("<H", i - cand)
            if m - 4 >= 15:
                out += length_bytes(m - 4 - 15)
            i += m
            anchor = i
        else:
            i += 1
    lit = src[anchor:]
    out.append(min(len(lit), 15) << 4)
    if len(lit) >= 15:
        out += length_bytes(len(lit) - 15)
    out += lit
    return bytes(out)


def lz4_frame(data):
    """LZ4 frame: independent 64 KiB blocks, content size and content checksum present."""
    flg = 0x40 | 0x20 | 0x08 | 0x04
    bd = 0x40
    desc = bytes([flg, bd]) + struct.pack("<Q", len(data))
    out = bytearray(struct.pack("<I", 0x184D2204)) + desc + bytes([(xxh32(desc) >> 8) & 0xFF])
    for s in range(0, len(data), 65536):
        block = data[s:s + 65536]
        comp = lz4_block(block)
        if len(comp) < len(block):
            out += struct.pack("<I", len(comp)) + comp
        else:
            out += struct.pack("<I", 0x80000000 | len(block)) + block
    out += struct.pack("<I", 0)
    out += struct.pack("<I", xxh32(data))
    return bytes(out)

# ---------------------------------------------------------------- rosbag2 sqlite3


SCHEMA_SQL = [
    "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY,ros_distro TEXT NOT NULL)",
    "CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version INTEGER NOT NULL,"
    "metadata TEXT NOT NULL)",
    "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
    "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL)",
    "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,"
    "timestamp INTEGER NOT NULL, data BLOB NOT NULL)",
    "CREATE INDEX timestamp_idx ON messages (timestamp ASC)",
]


def write_db3(path, messages, compress=False, empty_format_topics=()):
    if os.path.exists(path):
        os.remove(path)
    db = sqlite3.connect(path)
    for s in SCHEMA_SQL:
        db.execute(s)
    db.execute("INSERT INTO schema VALUES (3, 'humble')")
    ids = {}
    for topic, typ, _, _ in messages:
        if topic not in ids:
            ids[topic] = len(ids) + 1
            fmt = "" if topic in empty_format_topics else "cdr"
            db.execute("INSERT INTO topics VALUES (?,?,?,?,?)", (ids[topic], topic, typ, fmt, ""))
    # rows go in reversed time order so that the reader has to sort
    for topic, _, t, data in sorted(messages, key=lambda m: -m[2]):
        blob = zstd_frame(data) if compress else data
        db.execute("INSERT INTO messages (topic_id, timestamp, data) VALUES (?,?,?)",
                   (ids[topic], t, blob))
    db.commit()
    db.close()


def metadata_yaml(storage, files, messages, compression_format="", compression_mode=""):
    topics = {}
    for topic, typ, _, _ in messages:
        topics.setdefault(topic, [typ, 0])[1] += 1
    times = [m[2] for m in messages]
    lines = ["rosbag2_bagfile_information:", "  version: 5", f"  storage_identifier: {storage}",
             "  duration:", f"    nanoseconds: {max(times) - min(times)}", "  starting_time:",
             f"    nanoseconds_since_epoch: {min(times)}", f"  message_count: {len(messages)}",
             "  topics_with_message_count:"]
    for name, (typ, count) in topics.items():
        lines += ["    - topic_metadata:", f"        name: {name}", f"        type: {typ}",
                  "        serialization_format: cdr", '        offered_qos_profiles: ""',
                  f"      message_count: {count}"]
    lines += [f'  compression_format: "{compression_format}"',
              f'  compression_mode: "{compression_mode}"', "  relative_file_paths:"]
    lines += [f"    - {f}" for f in files]
    return "\n".join(lines) + "\n"

# ---------------------------------------------------------------- MCAP


MAGIC = b"\x89MCAP0\r\n"


def mstr(s):
    raw = s.encode()
    return struct.pack("<I", len(raw)) + raw


def mmap_ss(d):
    body = b"".join(mstr(k) + mstr(v) for k, v in d.items())
    return struct.pack("<I", len(body)) + body


def record(op, body):
    return struct.pack("<BQ", op, len(body)) + body


def schema_rec(sid, name, enc, data=b""):
    return record(0x03, struct.pack("<H", sid) + mstr(name) + mstr(enc) +
                  struct.pack("<I", len(data)) + data)


def channel_rec(cid, sid, topic, enc, meta=None):
    return record(0x04, struct.pack("<HH", cid, sid) + mstr(topic) + mstr(enc) + mmap_ss(meta or {}))


def message_rec(cid, seq, log_time, data):
    return record(0x05, struct.pack("<HIQQ", cid, seq, log_time, log_time) + data)


class McapWriter:
    def __init__(self):
        self.b = bytearray(MAGIC)
        self.b += record(0x01, mstr("ros2") + mstr("cdc-slam make_ros2_fixtures.py"))
        self.chunk_indexes = []
        self.summary_records = []

    def add(self, rec):
        self.b += rec

    def chunk(self, records, compression, times, crc=True):
        """Returns the byte offset of the chunk record and of its records field."""
        raw = b"".join(records)
        if compression == "zstd":
            comp = zstd_frame(raw)
        elif compression == "lz4":
            comp = lz4_frame(raw)
        else:
            comp = raw
        body = struct.pack("<QQQI", min(times), max(times), len(raw), zlib.crc32(raw) if crc else 0)
        body += mstr(compression) + struct.pack("<Q", len(comp))
        start = len(self.b)
        records_offset = start + 9 + len(body)
        body += comp
        self.b += record(0x06, body)
        chunk_len = len(self.b) - start
        # a message index record per chunk (content is not needed by the reader under test)
        mi_start = len(self.b)
        self.b += record(0x07, struct.pack("<H", 1) + struct.pack("<I", 16) + struct.pack("<QQ", 0, 0))
        mi_len = len(self.b) - mi_start
        self.chunk_indexes.append(record(
            0x08, struct.pack("<QQQQ", min(times), max(times), start, chunk_len) + mmap_u16_u64({}) +
            struct.pack("<Q", mi_len) + mstr(compression) + struct.pack("<QQ", len(comp), len(raw))))
        return start, records_offset

    def finish(self, summary):
        self.b += record(0x0F, struct.pack("<I", 0))
        summary_start = len(self.b)
        for r in summary + self.chunk_indexes:
            self.b += r
        so_start = len(self.b)
        self.b += record(0x0E, struct.pack("<BQQ", 0x08, summary_start, so_start - summary_start))
        self.b += record(0x02, struct.pack("<QQI", summary_start, so_start, 0))
        self.b += MAGIC
        return bytes(self.b)


def mmap_u16_u64(d):
    body = b"".join(struct.pack("<HQ", k, v) for k, v in d.items())
    return struct.pack("<I", len(body)) + body


def write_mcap(path, messages):
    """ros2.mcap: every fixture message plus a ros1 Imu and a json message."""
    w = McapWriter()
    types = {PC2: 1, IMU: 2, SCAN: 3}
    schemas = {1: schema_rec(1, PC2, "ros2msg", b"# definition omitted"),
               2: schema_rec(2, IMU, "ros2msg", b""), 3: schema_rec(3, SCAN, "ros2msg", b""),
               4: schema_rec(4, "sensor_msgs/Imu", "ros1msg", b""), 5: schema_rec(5, "diag", "jsonschema", b"{}")}
    topics = {}
    for topic, typ, _, _ in messages:
        if topic not in topics:
            topics[topic] = (len(topics) + 1, types[typ])
    channels = {topic: channel_rec(cid, sid, topic, "cdr", {"offered_qos_profiles": ""})
                for topic, (cid, sid) in topics.items()}
    ros1_cid, json_cid = 20, 21
    channels["/imu_ros1"] = channel_rec(ros1_cid, 4, "/imu_ros1", "ros1", {"md5sum": "x"})
    channels["/diagnostics_json"] = channel_rec(json_cid, 5, "/diagnostics_json", "json")

    by_topic = {}
    for m in messages:
        by_topic.setdefault(m[0], []).append(m)
    imu = by_topic["/imu"]
    # imu 0 outside any chunk, with its schema and channel at top level
    w.add(schemas[2])
    w.add(channels["/imu"])
    w.add(message_rec(topics["/imu"][0], 0, imu[0][2], imu[0][3]))
    # chunk A, uncompressed: clouds 0..3 in reversed order, and the absolute-time cloud
    recs = [schemas[1], channels["/points"], channels["/points_abs"]]
    group = list(reversed(by_topic["/points"])) + by_topic["/points_abs"]
    recs += [message_rec(topics[m[0]][0], s, m[2], m[3]) for s, m in enumerate(group)]
    chunk_a, chunk_a_records = w.chunk(recs, "", [m[2] for m in group])
    # attachment and metadata records (skipped by the reader)
    att = struct.pack("<QQ", 1, 2) + mstr("calib.txt") + mstr("text/plain") + struct.pack("<Q", 5) + b"hello"
    w.add(record(0x09, att + struct.pack("<I", zlib.crc32(att))))
    w.add(record(0x0C, mstr("run") + mmap_ss({"robot": "r0"})))
    # chunk B, zstd: the velodyne scans and the big-endian cloud
    recs = [schemas[3], channels["/velodyne_packets"], channels["/points_be"]]
    group = by_topic["/velodyne_packets"] + by_topic["/points_be"]
    recs += [message_rec(topics[m[0]][0], s, m[2], m[3]) for s, m in enumerate(group)]
    w.chunk(recs, "zstd", [m[2] for m in group], crc=False)
    # chunk C, lz4: imu 1..4, the ros1 imu and a json message; times overlap chunk A
    imu_ros1_time = imu[1][2] + 1
    recs = [schemas[4], channels["/imu_ros1"], schemas[5], channels["/diagnostics_json"]]
    recs += [message_rec(topics["/imu"][0], s, m[2], m[3]) for s, m in enumerate(imu[1:])]
    recs.append(message_rec(ros1_cid, 0, imu_ros1_time, make_imu_ros1(1)))
    recs.append(message_rec(json_cid, 0, imu[2][2] + 1, b'{"ok": true}'))
    w.chunk(recs, "lz4", [m[2] for m in imu[1:]] + [imu_ros1_time, imu[2][2] + 1])
    summary = list(schemas.values()) + list(channels.values())
    data = w.finish(summary)
    with open(path, "wb") as f:
        f.write(data)
    return {"chunk_a_offset": chunk_a, "chunk_a_records_offset": chunk_a_records,
            "imu_ros1_log_time": imu_ros1_time, "size": len(data)}


def write_small_mcap(path, bad_path):
    """A top-level scan (log time 10), an uncompressed chunk with a cloud (30) and an lz4 chunk with
    imu 0 and 1 (20, 40); bad_crc.mcap changes one byte of the cloud inside the uncompressed chunk."""
    w = McapWriter()
    w.add(schema_rec(3, SCAN, "ros2msg"))
    w.add(channel_rec(3, 3, "/velodyne_packets", "cdr"))
    w.add(message_rec(3, 0, 10, make_scan(0)))
    cloud = make_cloud(0)
    recs = [schema_rec(1, PC2, "ros2msg"), channel_rec(1, 1, "/points", "cdr"),
            message_rec(1, 0, 30, cloud)]
    chunk, records_offset = w.chunk(recs, "", [30])
    recs = [schema_rec(2, IMU, "ros2msg"), channel_rec(2, 2, "/imu", "cdr"),
            message_rec(2, 0, 20, make_imu(0)), message_rec(2, 1, 40, make_imu(1))]
    w.chunk(recs, "lz4", [20, 40])
    data = w.finish([schema_rec(1, PC2, "ros2msg"), channel_rec(1, 1, "/points", "cdr")])
    with open(path, "wb") as f:
        f.write(data)
    bad = bytearray(data)
    # a byte of the cloud's frame id inside the uncompressed chunk
    probe = bad.index(cloud[:16], records_offset)
    bad[probe + 20] ^= 0x5A
    with open(bad_path, "wb") as f:
        f.write(bytes(bad))
    return {"chunk_offset": chunk, "records_offset": records_offset, "flipped_byte": probe + 20,
            "size": len(data)}


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: make_ros2_fixtures.py OUT_DIR")
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    msgs = all_messages()
    info = {}

    d = os.path.join(out, "ros2_db3")
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    # split: file 0 has clouds, scans and imu 0..2; file 1 the rest (times interleave)
    first = [m for m in msgs if m[0] in ("/points", "/velodyne_packets") or
             (m[0] == "/imu" and m[2] < imu_log_time(3))]
    second = [m for m in msgs if m not in first]
    write_db3(os.path.join(d, "ros2_db3_0.db3"), first, empty_format_topics=("/velodyne_packets",))
    write_db3(os.path.join(d, "ros2_db3_1.db3"), second)
    with open(os.path.join(d, "metadata.yaml"), "w") as f:
        f.write(metadata_yaml("sqlite3", ["ros2_db3_0.db3", "ros2_db3_1.db3"], msgs))

    d = os.path.join(out, "ros2_db3_msgzstd")
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    write_db3(os.path.join(d, "ros2_db3_msgzstd_0.db3"), msgs, compress=True)
    with open(os.path.join(d, "metadata.yaml"), "w") as f:
        f.write(metadata_yaml("sqlite3", ["ros2_db3_msgzstd_0.db3"], msgs, "zstd", "MESSAGE"))

    d = os.path.join(out, "ros2_db3_filezstd")
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    plain = os.path.join(d, "tmp.db3")
    write_db3(plain, msgs)
    with open(plain, "rb") as f:
        packed = zstd_frame(f.read())
    os.remove(plain)
    with open(os.path.join(d, "ros2_db3_filezstd_0.db3.zstd"), "wb") as f:
        f.write(packed)
    with open(os.path.join(d, "metadata.yaml"), "w") as f:
        f.write(metadata_yaml("sqlite3", ["ros2_db3_filezstd_0.db3.zstd"], msgs, "zstd", "FILE"))

    info["ros2_mcap"] = write_mcap(os.path.join(out, "ros2.mcap"), msgs)
    d = os.path.join(out, "ros2_mcap")
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    shutil.copyfile(os.path.join(out, "ros2.mcap"), os.path.join(d, "ros2_mcap_0.mcap"))
    with open(os.path.join(d, "metadata.yaml"), "w") as f:
        f.write(metadata_yaml("mcap", ["ros2_mcap_0.mcap"], msgs))

    info["small_mcap"] = write_small_mcap(os.path.join(out, "small.mcap"),
                                          os.path.join(out, "bad_crc.mcap"))
    with open(os.path.join(out, "fixtures.json"), "w") as f:
        json.dump(info, f, indent=1)


def imu_log_time(k):
    v = imu_values(k)
    return stamp_ns(v["sec"], v["nsec"]) + 2000000


if __name__ == "__main__":
    main()
