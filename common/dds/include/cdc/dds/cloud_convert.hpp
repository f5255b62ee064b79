// Conversions between IDL point sequences and PCL clouds. PCL is only forward-declared here;
// the one translation unit that includes PCL headers is src/cloud_convert.cpp.
#pragma once

#include "cdc/dds/types.hpp"

#include <vector>

namespace pcl {
struct PointXYZI;
template <typename PointT>
class PointCloud;
}  // namespace pcl

namespace cdc::dds {

// Copies the message's points (x, y, z, intensity) into a PCL cloud.
void to_pcl(const dds_sequence_cdc_msg_PointXYZI& points, pcl::PointCloud<pcl::PointXYZI>& out);
void to_pcl(const dds_sequence_cdc_msg_LidarPoint& points, pcl::PointCloud<pcl::PointXYZI>& out);

// Fills storage from a PCL cloud; attach it to a message with borrow(msg.cloud, storage).
void from_pcl(const pcl::PointCloud<pcl::PointXYZI>& cloud, std::vector<cdc_msg_PointXYZI>& storage);

}  // namespace cdc::dds
