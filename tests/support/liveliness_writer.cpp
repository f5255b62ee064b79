// Test helper: a DDS process whose writer offers MANUAL_BY_TOPIC liveliness with a lease and
// asserts it from its work loop, like the central optimiser's liveliness writer: by writing a
// sample every period, or (--data-every N) by asserting and writing only every Nth period (0:
// never, assertions alone). Exits 0 on SIGINT/SIGTERM through the shutdown guard condition.
#include "cdc/dds/pubsub.hpp"
#include "dds_helpers.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  cdc::dds::ShutdownSignal::install();
  CLI::App app{"Test helper: a writer with MANUAL_BY_TOPIC liveliness, asserted periodically"};
  std::string topic_name;
  int lease_ms = 1000;
  int period_ms = 100;
  uint32_t domain = 0;
  int data_every = 1;
  app.add_option("--topic", topic_name, "topic name")->required();
  app.add_option("--data-every", data_every,
                 "write a sample every this many periods, assert in the others (0: never write)")
      ->check(CLI::Range(0, 1000000));
  app.add_option("--lease-ms", lease_ms, "liveliness lease [ms]")->check(CLI::Range(10, 60000));
  app.add_option("--period-ms", period_ms, "assertion period [ms]")->check(CLI::Range(1, 60000));
  app.add_option("--domain", domain, "DDS domain id")->check(CLI::Range(0, 232));
  CLI11_PARSE(app, argc, argv);

  try {
    cdc::dds::Participant participant(cdc::test::on_domain(domain));
    cdc::dds::Topic<cdc_msg_RobotStatus> topic(participant, topic_name);
    cdc::dds::Writer<cdc_msg_RobotStatus> writer(participant, topic,
                                                 cdc::dds::qos::monitored_writer(std::chrono::milliseconds(lease_ms)));
    cdc::test::SignalWaitSet ws(participant);

    cdc_msg_RobotStatus status{};
    status.robot_id = 0;
    status.is_central = true;
    status.last_keyframe_id = -1;
    std::printf("writer ready\n");
    std::fflush(stdout);
    for (long period = 0; !cdc::dds::ShutdownSignal::requested(); ++period) {
      if (data_every > 0 && period % data_every == 0) {
        writer.write(status);  // a write asserts liveliness
      } else {
        writer.assert_liveliness();
      }
      ws.wait(std::chrono::milliseconds(period_ms));
    }
    std::printf("writer stopped by signal %d\n", cdc::dds::ShutdownSignal::signal_number());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "liveliness_writer: %s\n", e.what());
    return 1;
  }
}
