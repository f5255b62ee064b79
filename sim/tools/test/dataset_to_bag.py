#!/usr/bin/python3
"""Writes one robot of a cdc-slam dataset folder as a bag, with writers independent of cdc_io:
ROS 1 through python3-rosbag (genpy serialises the messages), ROS 2 db3 and MCAP from the format
specifications (common/io/test/make_ros2_fixtures.py). Used by sim_import_test's round trip.

usage: dataset_to_bag.py DATASET OUT --format ros1|db3|mcap [--robot K] [--bad-cloud K]
Every sweep becomes a sensor_msgs/PointCloud2 on /points (x y z intensity float32, ring uint16, time
float32 [s] after the header stamp = the sweep's time); every IMU sample a sensor_msgs/Imu on /imu.
--bad-cloud K (ros1) gives sweep K a field layout that does not fit its point_step.
"""

import argparse
import os
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "..", "common", "io", "test"))

FIELDS = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7), ("ring", 16, 4), ("time", 18, 7)]
POINT_STEP = 22


def read_times(path):
    out = []
    for line in open(path):
        line = line.strip()
        if not line:
            continue
        sec, _, frac = line.partition(".")
        out.append(int(sec) * 1_000_000_000 + int((frac + "000000000")[:9]))
    return out


def read_sweep(robot_dir, k):
    name = "%06d.bin" % k
    xyzi = open(os.path.join(robot_dir, "velodyne", name), "rb").read()
    meta = open(os.path.join(robot_dir, "velodyne_meta", name), "rb").read()
    n = len(xyzi) // 16
    data = bytearray()
    for i in range(n):
        data += xyzi[16 * i:16 * i + 16] + meta[8 * i + 4:8 * i + 6] + meta[8 * i:8 * i + 4]
    return n, bytes(data)


def read_imu(robot_dir):
    path = os.path.join(robot_dir, "imu.csv")
    out = []
    if not os.path.exists(path):
        return out
    for line in open(path).readlines()[1:]:
        t, ax, ay, az, gx, gy, gz = line.strip().split(",")
        sec, _, frac = t.partition(".")
        out.append((int(sec) * 1_000_000_000 + int((frac + "000000000")[:9]),
                    (float(ax), float(ay), float(az)), (float(gx), float(gy), float(gz))))
    return out


def split(ns):
    return ns // 1_000_000_000, ns % 1_000_000_000


def write_ros1(out, sweeps, imu, bad_cloud=-1):
    import genpy
    import rosbag
    import make_ros1_fixtures as r1
    with rosbag.Bag(out, "w", chunk_threshold=256 * 1024) as bag:
        msgs = []
        for stamp, n, data in sweeps:
            m = r1.PointCloud2()
            m.header.stamp = genpy.Time(*split(stamp))
            m.header.frame_id = "lidar"
            m.height, m.width = 1, n
            m.fields = [r1.PointField(name=f, offset=o, datatype=d, count=1) for f, o, d in FIELDS]
            if len(msgs) == bad_cloud:
                m.fields[-1].offset = POINT_STEP  # "time" starts where the point ends
            m.is_bigendian = False
            m.point_step, m.row_step = POINT_STEP, POINT_STEP * n
            m.data = data
            m.is_dense = True
            msgs.append((stamp, "/points", m))
        for t, a, g in imu:
            m = r1.Imu()
            m.header.stamp = genpy.Time(*split(t))
            m.header.frame_id = "imu"
            m.orientation.w = 1.0
            m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = g
            m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = a
            msgs.append((t, "/imu", m))
        for t, topic, m in sorted(msgs, key=lambda x: x[0]):
            bag.write(topic, m, t=genpy.Time(*split(t)))


def ros2_messages(sweeps, imu):
    import make_ros2_fixtures as r2
    out = []
    for stamp, n, data in sweeps:
        c = r2.Cdr()
        r2.header(c, *split(stamp), "lidar")
        r2.cloud_body(c, n, FIELDS, POINT_STEP, data, is_dense=True)
        out.append(("/points", "sensor_msgs/msg/PointCloud2", stamp, c.message()))
    for t, a, g in imu:
        c = r2.Cdr()
        r2.header(c, *split(t), "imu")
        for v in (0.0, 0.0, 0.0, 1.0) + (0.0,) * 9 + g + (0.0,) * 9 + a + (0.0,) * 9:
            c.f64(v)
        out.append(("/imu", "sensor_msgs/msg/Imu", t, c.message()))
    return sorted(out, key=lambda m: m[2])


def write_db3(out, messages):
    import make_ros2_fixtures as r2
    os.makedirs(out, exist_ok=True)
    r2.write_db3(os.path.join(out, "bag_0.db3"), messages)
    with open(os.path.join(out, "metadata.yaml"), "w") as f:
        f.write(r2.metadata_yaml("sqlite3", ["bag_0.db3"], messages))


def write_mcap(out, messages):
    import make_ros2_fixtures as r2
    w = r2.McapWriter()
    schemas = {"sensor_msgs/msg/PointCloud2": r2.schema_rec(1, "sensor_msgs/msg/PointCloud2", "ros2msg", b""),
               "sensor_msgs/msg/Imu": r2.schema_rec(2, "sensor_msgs/msg/Imu", "ros2msg", b"")}
    channels = {"/points": r2.channel_rec(1, 1, "/points", "cdr", {}), "/imu": r2.channel_rec(2, 2, "/imu", "cdr", {})}
    cid = {"/points": 1, "/imu": 2}
    recs = list(schemas.values()) + list(channels.values())
    recs += [r2.message_rec(cid[m[0]], i, m[2], m[3]) for i, m in enumerate(messages)]
    w.chunk(recs, "zstd", [m[2] for m in messages])
    with open(out, "wb") as f:
        f.write(w.finish(list(schemas.values()) + list(channels.values())))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset")
    ap.add_argument("out")
    ap.add_argument("--format", choices=["ros1", "db3", "mcap"], required=True)
    ap.add_argument("--robot", type=int, default=0)
    ap.add_argument("--bad-cloud", type=int, default=-1)
    a = ap.parse_args()
    rd = os.path.join(a.dataset, "robot_%d" % a.robot)
    times = read_times(os.path.join(rd, "times.txt"))
    sweeps = [(t,) + read_sweep(rd, k) for k, t in enumerate(times)]
    imu = read_imu(rd)
    if a.format == "ros1":
        write_ros1(a.out, sweeps, imu, a.bad_cloud)
    elif a.format == "db3":
        write_db3(a.out, ros2_messages(sweeps, imu))
    else:
        write_mcap(a.out, ros2_messages(sweeps, imu))


if __name__ == "__main__":
    main()
