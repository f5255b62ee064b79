#include "mode_files.hpp"

#include <cstdio>
#include <stdexcept>
#include <utility>

namespace cdc::peer {

ModeFiles::ModeFiles(std::string path) : path_(std::move(path)) {
  if (path_.empty()) return;
  timeline_.open(path_);
  if (!timeline_) throw std::runtime_error(path_ + ": cannot write the mode timeline");
  timeline_ << "wall_ns,sim_ns,robot,from,to,reason,distance_m,keyframes\n" << std::flush;
}

void ModeFiles::transition(const Transition& t, int64_t wall_ns, int64_t sim_ns, uint32_t robot, size_t keyframes) {
  if (!timeline_.is_open()) return;
  timeline_ << wall_ns << ',' << sim_ns << ',' << robot << ',' << to_string(t.from) << ',' << to_string(t.to) << ','
            << to_string(t.reason) << ',' << (t.distance_m ? std::to_string(*t.distance_m) : std::string("")) << ','
            << keyframes << '\n'
            << std::flush;
}

void ModeFiles::now(const BackendState& s) const {
  if (path_.empty()) return;
  const std::string now_path = path_ + ".now", tmp = now_path + ".tmp";
  std::ofstream(tmp, std::ios::trunc) << to_string(s.mode) << ' ' << s.keyframes << ' ' << s.transitions << ' '
                                      << (s.central_alive ? 1 : 0) << ' ' << s.acknowledged + 1 << '\n';
  std::rename(tmp.c_str(), now_path.c_str());
}

}  // namespace cdc::peer
