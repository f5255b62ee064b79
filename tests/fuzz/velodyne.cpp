// Velodyne packets (common/io/velodyne): the header reader, the per-packet decoder and the sweep
// assembler over a stream of packets. The input after the selector is cut into 1206-byte packets (the
// last may be short); each arrives 1.3 ms after the previous one. Selector % 7: the model (6: from
// each packet's product id, with the VLP-16's calibration); bit 3 of selector / 7: dual returns
// forced, else the packets' own return mode.
#include "cdc/io/velodyne.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace io = cdc::io;
  const cdc::fuzz::Input in(data, size);
  const int m = in.selector % 7;
  io::VelodyneDecoderOptions options;
  if (m < 6) options.model = static_cast<io::VelodyneModel>(m);
  if ((in.selector / 7) % 2 == 1) options.return_mode = io::VelodyneReturnMode::kDual;
  const io::VelodyneCalibration calibration =
      io::default_velodyne_calibration(options.model.value_or(io::VelodyneModel::kVLP16));
  io::VelodyneDecoder decoder(calibration, options);
  io::VelodyneSweepAssembler assembler(calibration, options);
  std::vector<io::VelodynePoint> points;
  int64_t stamp_ns = 1'000'000'000;
  for (size_t at = 0; at < in.rest.size(); at += io::kVelodynePacketSize) {
    const std::span<const uint8_t> packet = in.rest.subspan(at, std::min(io::kVelodynePacketSize, in.rest.size() - at));
    (void)io::read_velodyne_packet_header(packet);
    (void)decoder.decode(packet, stamp_ns, points);
    (void)assembler.add_packet(packet, stamp_ns);
    while (assembler.has_sweep()) {
      int64_t sweep_stamp = 0;
      (void)io::to_sweep(assembler.take(), sweep_stamp);
    }
    stamp_ns += 1'300'000;
  }
  assembler.flush();
  while (assembler.has_sweep()) {
    int64_t sweep_stamp = 0;
    (void)io::to_sweep(assembler.take(), sweep_stamp);
  }
  return 0;
}
