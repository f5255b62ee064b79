// pcap captures (common/io/pcap): link layers, IPv4 headers, fragment reassembly, UDP datagrams.
#include "cdc/io/pcap.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path path = cdc::fuzz::write_file("capture.pcap", {data, size});
  cdc::fuzz::refusals_pass([&] {
    cdc::io::PcapReader reader(path);
    cdc::io::UdpDatagram d;
    for (size_t i = 0; i < 100000 && reader.next(d); ++i) {}
    (void)reader.stats();
  });
  return 0;
}
