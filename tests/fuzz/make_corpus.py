#!/usr/bin/python3
"""Writes the seed corpus of the fuzz harnesses: tests/fuzz/make_corpus.py [OUT_DIR] (default: the
corpus/ folder beside this script, one subfolder per harness).

Seeds are small valid (and a few nearly valid) inputs, generated here or by the io library's own test
fixture writers (make_ros1_fixtures.py, which needs python3-rosbag, and make_ros2_fixtures.py), never
copied from reference data. A harness whose first input byte selects a parser variant gets that byte
prepended (see each harness's comment). Output is deterministic.
"""

import math
import os
import shutil
import sqlite3
import struct
import sys
import tempfile
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "common", "io", "test"))


class Corpus:
    def __init__(self, out):
        self.out = out

    def add(self, harness, name, data, selector=None):
        if isinstance(data, str):
            data = data.encode()
        if selector is not None:
            data = bytes([selector]) + data
        d = os.path.join(self.out, harness)
        os.makedirs(d, exist_ok=True)
        with open(os.path.join(d, name), "wb") as f:
            f.write(data)


def read(path, limit=4096):
    with open(os.path.join(ROOT, path), "rb") as f:
        return f.read()[:limit]


# ------------------------------------------------------------------------- text formats


def g2o(c):
    c.add("g2o", "se3", "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n"
          "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 " + " ".join(
              "1" if i == j else "0" for i in range(6) for j in range(i, 6)) + "\n", 0)
    info3 = "100 0 0 100 0 1000"
    c.add("g2o", "se2", "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0.1\nEDGE_SE2 0 1 1 0 0.1 " + info3 + "\n"
          "EDGE_SE2 1 2 1 0 0.1 " + info3 + "\n", 1)
    a0, b0 = (ord("a") << 56), (ord("b") << 56)
    c.add("g2o", "gtsam_keys", f"VERTEX_SE3:QUAT {a0} 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT {b0 + 3} 2 1 0 0 0 0.7071 0.7071\n"
          f"EDGE_SE3:QUAT {a0} {b0 + 3} 2 1 0 0 0 0.7071 0.7071 " + " ".join(
              "10" if i == j else "0" for i in range(6) for j in range(i, 6)) + "\n# comment\n", 0)
    c.add("g2o", "edges_only", "EDGE_SE2 0 1 1 0 0 " + info3 + "\nFIX 0\nBADLINE 1 2\n", 1)


def trajectory(c):
    tum = "# t x y z qx qy qz qw\n0.0 0 0 0 0 0 0 1\n0.1 1 0 0 0 0 0 1\n0.2 2 0.1 0 0 0 0.0998 0.995\n"
    kitti = "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0.5 0 1 0 0 0 0 1 1.2\n"
    times = "0.000000e+00\n1.037359e-01\n"
    c.add("trajectory", "tum", tum, 0)
    c.add("trajectory", "kitti", kitti, 1)
    c.add("trajectory", "times_kitti", times.replace("\n", " ", 1) + kitti, 2)
    c.add("trajectory", "times", times, 3)
    c.add("trajectory", "detect", tum, 4)
    c.add("trajectory", "seconds", "1700000000.123456789", 4)


def config(c):
    c.add("config", "generic", "rate: 10\na:\n  count: 3\n  b: {id: 7}\nenabled: true\nname: x\nlist: [1, 2.5]\n", 0)
    files = ["services/central_optimiser/config/central_optimiser.yaml", "services/descriptor/config/descriptor.yaml",
             "services/frontend/config/frontend.yaml", "services/loop_closure/config/loop_closure.yaml",
             "services/map/config/map.yaml", "services/velodyne_driver/config/velodyne.yaml",
             "services/peer_optimiser/config/peer_optimiser.yaml", "deploy/swarms/kitti05_demo.yaml"]
    for i, f in enumerate(files):
        c.add("config", os.path.basename(f), read(f), i + 1)


def scenario(c):
    for f in sorted(os.listdir(os.path.join(ROOT, "sim", "scenarios"))):
        if f.endswith(".yaml"):
            c.add("scenario", f, read(os.path.join("sim", "scenarios", f)))


def dataset(c):
    c.add("dataset", "dataset.json", '{"name": "d", "source": "simulated", "robots": 3, "scans": 10, "points": 100,'
          ' "central_id": 200, "out_of_range_periods": 0, "point_times": "sensor", "sweep_period_s": 0.1,'
          ' "radio": "simulated", "poses": "ground_truth"}\n', 0)
    c.add("dataset", "imu.csv", "t,ax,ay,az,gx,gy,gz\n0.000,0.1,0,9.81,0,0,0.01\n0.005,0.1,0,9.8,0,0,0.02\n", 1)
    c.add("dataset", "calib.yaml", "lidar: vlp16\nimu_rate_hz: 200\n"
          "T_lidar_imu: {position: [0.1, 0, -0.05], orientation: [0, 0, 0, 1]}\n", 2)
    c.add("dataset", "calib.txt", "P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: 0 -1 0 0 0 0 -1 -0.08 1 0 0 -0.27\n", 3)
    lasers = "".join(f"  - {{laser_id: {i}, rot_correction: 0.0, vert_correction: {math.radians(-15 + 2 * i):.6f},"
                     f" dist_correction: 0.0, vert_offset_correction: 0.0, horiz_offset_correction: 0.0}}\n"
                     for i in range(16))
    c.add("dataset", "velodyne_vlp16.yaml", "num_lasers: 16\ndistance_resolution: 0.002\nlasers:\n" + lasers, 4)


# ------------------------------------------------------------------------- binary formats


def cloud(c):
    pts = [(1.0 + i, -0.5 * i, 0.25 * i, 0.1 * i) for i in range(4)]
    c.add("cloud", "kitti.bin", b"".join(struct.pack("<4f", *p) for p in pts), 0)
    c.add("cloud", "meta", b"".join(struct.pack("<fHH", 0.001 * i, i, 0) for i in range(4)), 1 + 4)
    header = ("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity ring time\nSIZE 4 4 4 4 2 4\nTYPE F F F F U F\n"
              "COUNT 1 1 1 1 1 1\nWIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\n")
    c.add("cloud", "ascii.pcd", header + "DATA ascii\n" + "".join(
        f"{x} {y} {z} {i} {k} {0.001 * k}\n" for k, (x, y, z, i) in enumerate(pts)), 2)
    c.add("cloud", "binary.pcd", (header + "DATA binary\n").encode() + b"".join(
        struct.pack("<4fHf", *p, k, 0.001 * k) for k, p in enumerate(pts)), 2)
    ply = ("ply\nformat {}\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
           "property float intensity\nend_header\n")
    c.add("cloud", "ascii.ply", ply.format("ascii 1.0") + "".join(" ".join(map(str, p)) + "\n" for p in pts), 3)
    c.add("cloud", "binary.ply", ply.format("binary_little_endian 1.0").encode() + b"".join(
        struct.pack("<4f", *p) for p in pts), 3)


def velodyne_packet(product, k, flags=(0xEEFF,), ret=0x37):
    """One 1206-byte packet: 12 blocks (flag, azimuth, 32 returns), GPS time, return mode, product id."""
    out = bytearray()
    for b in range(12):
        az = (k * 12 + b) * 40 % 36000
        out += struct.pack("<HH", flags[b % len(flags)], az)
        for ch in range(32):
            out += struct.pack("<HB", 2500 + 37 * ch + 11 * b, (ch * 7) % 256)
    out += struct.pack("<IBB", 1000 * k, ret, product)
    return bytes(out)


def velodyne(c):
    # selector % 7 = model: VLP16, VLP32C, HDL32E, HDL64E, HDL64E_S3, VLS128, auto.
    ids = {0: 0x22, 1: 0x28, 2: 0x21, 5: 0xA1, 6: 0x22}
    for m, name in enumerate(["vlp16", "vlp32c", "hdl32e", "hdl64e", "hdl64e_s3", "vls128", "auto"]):
        flags = (0xEEFF, 0xDDFF) if m in (3, 4) else (0xEEFF, 0xDDFF, 0xCCFF, 0xBBFF) if m == 5 else (0xEEFF,)
        c.add("velodyne", name, velodyne_packet(ids.get(m, 0), 0, flags) + velodyne_packet(ids.get(m, 0), 1, flags), m)
    c.add("velodyne", "vlp16_dual", velodyne_packet(0x22, 0, ret=0x39) + velodyne_packet(0x22, 1, ret=0x39), 7 + 6)


def ipv4(payload, src, dst, ident=1, frag=0, proto=17):
    return struct.pack(">BBHHHBBH4s4s", 0x45, 0, 20 + len(payload), ident, frag, 64, proto, 0,
                       bytes(src), bytes(dst)) + payload


def pcap(c):
    def file(linktype, frames, magic=0xA1B2C3D4):
        out = struct.pack("<IHHiIII", magic, 2, 4, 0, 0, 65535, linktype)
        for i, f in enumerate(frames):
            out += struct.pack("<IIII", 1700000000 + i, 1000 * i, len(f), len(f)) + f
        return out
    eth = b"\xff" * 6 + b"\x02\x00\x00\x00\x00\x01" + b"\x08\x00"
    src, dst = (192, 168, 1, 201), (255, 255, 255, 255)
    udp = struct.pack(">HHHH", 2368, 2368, 8 + 24, 0) + bytes(range(24))
    c.add("pcap", "ethernet_udp", file(1, [eth + ipv4(udp, src, dst), eth + ipv4(udp, src, dst, 2)]))
    c.add("pcap", "fragments", file(1, [eth + ipv4(udp[:16], src, dst, 7, 0x2000), eth + ipv4(udp[16:], src, dst, 7, 2)]))
    c.add("pcap", "cooked_ns", file(113, [b"\x00\x00\x00\x01\x00\x06" + b"\x02" * 8 + b"\x08\x00" + ipv4(udp, src, dst)],
                                    0xA1B23C4D))
    c.add("pcap", "raw_ip", file(101, [ipv4(udp, src, dst), ipv4(b"\x00" * 8, src, dst, 3, proto=6)]))


def spread3(v):
    return sum(((v >> i) & 1) << (3 * i) for i in range(16))


def compact(c):
    # Clouds: uint16 count, uint8 resolution [mm] - 1, then the packed planes of sorted Morton deltas.
    for name, res_mm, pts in [("cloud_line", 10, [(i, -2 * i, 3) for i in range(20)]),
                              ("cloud_box", 50, [(x, y, z) for x in (-3, 0, 5) for y in (-1, 2) for z in (0, 7)]),
                              ("cloud_int16_ends", 64, [(-32768,) * 3, (32767,) * 3]),
                              # A keyframe's cloud as the peer optimiser packs it for the map (2 cm
                              # grid): rings of points 5 to 40 m around the sensor.
                              ("cloud_keyframe_2cm", 20,
                               [(round(r * math.cos(math.radians(a)) / 0.02), round(r * math.sin(math.radians(a)) / 0.02),
                                 round((-1.5 + 0.1 * k) / 0.02))
                                for k, r in enumerate((5, 10, 20, 40)) for a in range(0, 360, 3)])]:
        codes = sorted(spread3(x & 0xFFFF ^ 0x8000) | spread3(y & 0xFFFF ^ 0x8000) << 1 |
                       spread3(z & 0xFFFF ^ 0x8000) << 2 for x, y, z in pts)
        deltas = [b - a for a, b in zip([0] + codes, codes)]
        raw = bytes((d >> (8 * k)) & 0xFF for k in range(6) for d in deltas)
        c.add("compact", name, struct.pack("<HB", len(pts), res_mm - 1) + zlib.compress(raw, 9), 0)
    # Descriptors: uint16 rings, uint16 sectors, float scale, then the deflated cells.
    cells = bytes((r * 3 + s) % 200 if (r + s) % 4 else 0 for r in range(20) for s in range(60))
    c.add("compact", "descriptor_20x60", struct.pack("<HHf", 20, 60, 0.02) + zlib.compress(cells, 9), 1)
    c.add("compact", "descriptor_2x3", struct.pack("<HHf", 2, 3, 0.5) + zlib.compress(bytes(6), 9), 1)


# ------------------------------------------------------------------------- recordings


def ros_messages_and_bags(c):
    import make_ros2_fixtures as r2
    c.add("ros_messages", "cloud_cdr", r2.make_cloud(0), 0)
    c.add("ros_messages", "cloud_be_cdr", r2.make_cloud_be(), 0)
    c.add("ros_messages", "imu_cdr", r2.make_imu(0), 1)
    c.add("ros_messages", "scan_cdr", r2.make_scan(0)[:2600], 2)
    tmp = tempfile.mkdtemp()
    try:
        msgs = [m for m in r2.all_messages() if m[1] != r2.SCAN][:3]
        db = os.path.join(tmp, "small.db3")
        r2.write_db3(db, msgs)
        con = sqlite3.connect(db)
        con.execute("PRAGMA page_size=512")
        con.execute("VACUUM")
        con.close()
        with open(db, "rb") as f:
            c.add("bag", "small.db3", f.read(), 0)
        small = os.path.join(tmp, "small.mcap")
        r2.write_small_mcap(small, os.path.join(tmp, "bad.mcap"))
        with open(small, "rb") as f:
            c.add("bag", "small.mcap", f.read(), 0)
        c.add("bag", "metadata.yaml", r2.metadata_yaml("sqlite3", ["a_0.db3"], msgs), 1)
        ros1_bags(c, tmp)
    finally:
        shutil.rmtree(tmp)


def ros1_bags(c, tmp):
    try:
        import make_ros1_fixtures as r1
        import rosbag
    except ImportError:
        print("make_corpus: python3-rosbag missing; no ROS 1 seeds", file=sys.stderr)
        return
    for comp in ("none", "lz4", "bz2"):
        path = os.path.join(tmp, comp + ".bag")
        with rosbag.Bag(path, "w", compression=comp) as bag:
            bag.write("/imu", r1.make_imu(0), r1.log_time("/imu", 0))
            bag.write("/points", r1.make_cloud(1), r1.log_time("/points", 1))
        with open(path, "rb") as f:
            c.add("bag", "ros1_" + comp + ".bag", f.read(), 0)
    c.add("ros_messages", "imu_ros1", serialise(r1.make_imu(1)), 1 + 3)
    c.add("ros_messages", "cloud_ros1", serialise(r1.make_cloud(2)), 0 + 3)


def serialise(msg):
    import io
    buf = io.BytesIO()
    msg.serialize(buf)
    return buf.getvalue()


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(HERE, "corpus")
    if os.path.isdir(out):
        shutil.rmtree(out)
    c = Corpus(out)
    for make in (g2o, trajectory, config, scenario, dataset, cloud, velodyne, pcap, compact, ros_messages_and_bags):
        make(c)


if __name__ == "__main__":
    main()
