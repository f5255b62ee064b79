// Test helper: a DDS process that reads RobotStatus samples on one topic (reliable, volatile, the
// event-stream QoS the services use) and prints "sample <last_keyframe_id>" for each, flushed, so
// that a test can see exactly which samples crossed. Exits 0 on SIGINT/SIGTERM.
#include "cdc/dds/pubsub.hpp"
#include "dds_helpers.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  cdc::dds::ShutdownSignal::install();
  CLI::App app{"Test helper: prints the id (last_keyframe_id) of every RobotStatus sample read on a topic"};
  std::string topic_name;
  uint32_t domain = 0;
  app.add_option("--topic", topic_name, "topic name")->required();
  app.add_option("--domain", domain, "DDS domain id")->check(CLI::Range(0, 232));
  CLI11_PARSE(app, argc, argv);

  try {
    cdc::dds::Participant participant(cdc::test::on_domain(domain));
    cdc::dds::Topic<cdc_msg_RobotStatus> topic(participant, topic_name);
    cdc::dds::Reader<cdc_msg_RobotStatus> reader(participant, topic, cdc::dds::qos::event_stream());
    cdc::test::SignalWaitSet ws(participant);
    cdc::dds::ReadCondition data(reader.handle());
    ws.waitset().attach(data.handle(), 1);
    std::printf("reader ready\n");
    std::fflush(stdout);
    while (!cdc::dds::ShutdownSignal::requested()) {
      reader.take(256).for_each_valid([](const cdc_msg_RobotStatus& m, const dds_sample_info_t&) {
        std::printf("sample %lld\n", static_cast<long long>(m.last_keyframe_id));
      });
      std::fflush(stdout);
      ws.wait(std::chrono::milliseconds(100));
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sample_reader: %s\n", e.what());
    return 1;
  }
}
