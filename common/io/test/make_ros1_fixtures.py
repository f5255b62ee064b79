#!/usr/bin/python3
"""Writes the ROS 1 test bags of io_ros1_bag_test with python3-rosbag (an implementation independent
of cdc_io): usage make_ros1_fixtures.py OUT_DIR.

Message classes come from genpy.dynamic and the standard .msg definitions below (sensor_msgs and
velodyne_msgs need not be installed); genpy serialises the messages, rosbag writes the container.
The values follow formulas that ros1_bag_test.cpp repeats; OUT_DIR/manifest.txt lists, per bag, every
message written (bag topic index sec nsec) in write order.
"""

import os
import shutil
import struct
import sys

import genpy
import genpy.dynamic
import rosbag

SEP = "\n" + "=" * 80 + "\n"
HEADER = """uint32 seq
time stamp
string frame_id"""
POINT_FIELD = """uint8 INT8    = 1
uint8 UINT8   = 2
uint8 INT16   = 3
uint8 UINT16  = 4
uint8 INT32   = 5
uint8 UINT32  = 6
uint8 FLOAT32 = 7
uint8 FLOAT64 = 8
string name
uint32 offset
uint8  datatype
uint32 count"""
POINT_CLOUD2 = """Header header
uint32 height
uint32 width
PointField[] fields
bool    is_bigendian
uint32  point_step
uint32  row_step
uint8[] data
bool is_dense""" + SEP + "MSG: std_msgs/Header\n" + HEADER + SEP + "MSG: sensor_msgs/PointField\n" + POINT_FIELD
IMU = """Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance""" + SEP + "MSG: std_msgs/Header\n" + HEADER + SEP + \
    "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w" + SEP + \
    "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z"
VELODYNE_SCAN = """Header           header
VelodynePacket[] packets""" + SEP + "MSG: std_msgs/Header\n" + HEADER + SEP + \
    "MSG: velodyne_msgs/VelodynePacket\ntime stamp\nuint8[1206] data"

PointCloud2 = genpy.dynamic.generate_dynamic("sensor_msgs/PointCloud2", POINT_CLOUD2)["sensor_msgs/PointCloud2"]
_imu_classes = genpy.dynamic.generate_dynamic("sensor_msgs/Imu", IMU)
Imu = _imu_classes["sensor_msgs/Imu"]
_velodyne_classes = genpy.dynamic.generate_dynamic("velodyne_msgs/VelodyneScan", VELODYNE_SCAN)
VelodyneScan = _velodyne_classes["velodyne_msgs/VelodyneScan"]
VelodynePacket = _velodyne_classes["velodyne_msgs/VelodynePacket"]
PointField = genpy.dynamic.generate_dynamic("sensor_msgs/PointCloud2", POINT_CLOUD2)["sensor_msgs/PointField"]

# The definitions above are the standard ones: their md5sums are those of real recordings.
assert PointCloud2._md5sum == "1158d486dd51d683ce2f1be655c3c181", PointCloud2._md5sum
assert Imu._md5sum == "6a62c6daae103f4ff57a132d6f95cec2", Imu._md5sum
assert VelodyneScan._md5sum == "50804fc9533a0e579e6322c04ae70566", VelodyneScan._md5sum

FLOAT32, UINT16 = 7, 4
POINT_STEP = 22  # x y z intensity (float32) ring (uint16) time (float32)


def stamp(sec, nsec):
    return genpy.Time(sec, nsec)


def make_imu(i):
    m = Imu()
    m.header.seq = i
    m.header.stamp = stamp(1000 + i, 1000 * i + 7)
    m.header.frame_id = "imu_link"
    m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w = 0.125 * i, -0.25, 0.5, 0.75
    m.orientation_covariance = [100.0 + k for k in range(9)]
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = 0.5 * i, -1.5, 2.25
    m.angular_velocity_covariance = [200.0 + k for k in range(9)]
    m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = i + 0.125, -9.75, 3.5
    m.linear_acceleration_covariance = [300.0 + k for k in range(9)]
    return m


def cloud_width(i):
    return 3 + i % 4


def make_cloud(i):
    m = PointCloud2()
    m.header.seq = i
    m.header.stamp = stamp(2000 + i, 500)
    m.header.frame_id = "velodyne"
    m.height = 1
    m.width = cloud_width(i)
    m.fields = [PointField(name=n, offset=o, datatype=t, count=1)
                for n, o, t in [("x", 0, FLOAT32), ("y", 4, FLOAT32), ("z", 8, FLOAT32),
                                ("intensity", 12, FLOAT32), ("ring", 16, UINT16), ("time", 18, FLOAT32)]]
    m.is_bigendian = False
    m.point_step = POINT_STEP
    m.row_step = POINT_STEP * m.width
    m.data = b"".join(struct.pack("<ffffHf", i + 0.25 * j, -0.5 * j, 1.5, 10.0 * j, j, 0.001953125 * j)
                      for j in range(m.width))
    m.is_dense = i % 2 == 0
    return m


def make_scan(i):
    m = VelodyneScan()
    m.header.seq = i
    m.header.stamp = stamp(3000 + i, 0)
    m.header.frame_id = "velodyne"
    m.packets = [VelodynePacket(stamp=stamp(3000 + i, 1000 * k + 1),
                                data=bytes((b + 7 * k + 13 * i) % 256 for b in range(1206)))
                 for k in range(2)]
    return m


# Log times [ns]: IMU at 100 s + 10 ms * i, scans 2 ms and clouds 5 ms after it.
def log_time(topic, i):
    offset_ns = {"/imu": 0, "/velodyne_packets": 2_000_000, "/points": 5_000_000}[topic]
    return genpy.Time(100, 0) + genpy.Duration(0, 10_000_000 * i + offset_ns)


MAKERS = {"/imu": make_imu, "/points": make_cloud, "/velodyne_packets": make_scan}


class Writer:
    def __init__(self, out_dir, name, manifest, **bag_args):
        self.name, self.manifest = name, manifest
        self.path = os.path.join(out_dir, name)
        self.bag = rosbag.Bag(self.path, "w", **bag_args)

    def write(self, topic, i, msg=None):
        t = log_time(topic, i)
        self.bag.write(topic, msg if msg is not None else MAKERS[topic](i), t)
        self.manifest.append(f"{self.name} {topic} {i} {t.secs} {t.nsecs}")

    def snapshot(self, name):
        """Copies the bag as it is on disk now, before close(): a recording that was not closed."""
        self.bag._file.flush()
        shutil.copyfile(self.path, os.path.join(os.path.dirname(self.path), name))
        self.manifest.extend(line.replace(self.name, name, 1) for line in self.manifest
                             if line.startswith(self.name + " "))

    def close(self):
        self.bag.close()


def mixed_order(n):
    """Write order of the three-topic bags: clouds are written two steps late, so that the small chunks
    overlap in time and time order differs from file order."""
    order = []
    for i in range(n):
        order += [("/imu", i), ("/velodyne_packets", i)]
        if i >= 2:
            order.append(("/points", i - 2))
    order += [("/points", i) for i in range(max(n - 2, 0), n)]
    return order


def main():
    out_dir = sys.argv[1]
    os.makedirs(out_dir, exist_ok=True)
    manifest = []

    for compression in ("none", "bz2", "lz4"):
        w = Writer(out_dir, f"mixed_{compression}.bag", manifest, compression=compression, chunk_threshold=1024)
        for topic, i in mixed_order(20):
            w.write(topic, i)
        w.close()

    # The bag for the truncation tests, in time order: two chunks of two connections each (so two
    # index data records follow each chunk).
    for compression in ("none", "lz4"):
        w = Writer(out_dir, f"small_{compression}.bag", manifest, compression=compression, chunk_threshold=1500)
        for topic, i in [("/imu", 0), ("/points", 0), ("/imu", 1), ("/points", 1), ("/imu", 2)]:
            w.write(topic, i)
        w.close()

    # Recordings that were not closed: one copied after a chunk was closed (no index section), one
    # copied while an uncompressed chunk was open (its records follow a chunk header of size 0).
    w = Writer(out_dir, "unclosed.bag", manifest, compression="none", chunk_threshold=1024)
    order = mixed_order(6)
    for topic, i in order[:9]:
        w.write(topic, i)
    assert not w.bag._chunk_open
    w.snapshot("unclosed_between_chunks.bag")
    w.write(*order[9])
    assert w.bag._chunk_open
    w.snapshot("unclosed_in_chunk.bag")
    w.close()
    manifest[:] = [line for line in manifest if not line.startswith("unclosed.bag ")]

    # A cloud whose data (65 bytes) disagree with row_step * height (66).
    w = Writer(out_dir, "bad_cloud.bag", manifest)
    bad = make_cloud(0)
    bad.data = bad.data[:65]
    w.write("/points", 0, bad)
    w.close()

    with open(os.path.join(out_dir, "manifest.txt"), "w") as f:
        f.write("\n".join(manifest) + "\n")


if __name__ == "__main__":
    main()
