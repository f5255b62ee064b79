// The DDS layer's only translation unit that includes PCL.
#include "cdc/dds/cloud_convert.hpp"

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

namespace cdc::dds {

namespace {
template <class Seq>
void copy_xyzi(const Seq& points, pcl::PointCloud<pcl::PointXYZI>& out) {
  out.clear();
  out.reserve(points._length);
  for (uint32_t i = 0; i < points._length; ++i) {
    const auto& p = points._buffer[i];
    pcl::PointXYZI q;
    q.x = p.x;
    q.y = p.y;
    q.z = p.z;
    q.intensity = p.intensity;
    out.push_back(q);
  }
  out.width = static_cast<uint32_t>(out.size());
  out.height = 1;
  out.is_dense = true;
}
}  // namespace

void to_pcl(const dds_sequence_cdc_msg_PointXYZI& points, pcl::PointCloud<pcl::PointXYZI>& out) {
  copy_xyzi(points, out);
}

void to_pcl(const dds_sequence_cdc_msg_LidarPoint& points, pcl::PointCloud<pcl::PointXYZI>& out) {
  copy_xyzi(points, out);
}

void from_pcl(const pcl::PointCloud<pcl::PointXYZI>& cloud, std::vector<cdc_msg_PointXYZI>& storage) {
  storage.resize(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    storage[i] = cdc_msg_PointXYZI{cloud[i].x, cloud[i].y, cloud[i].z, cloud[i].intensity};
  }
}

}  // namespace cdc::dds
