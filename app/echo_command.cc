// monoplane echo TOPIC: subscribe to a monoplane / ROS 2 topic and print one summary line per
// message.
#include <csignal>
#include <cstdio>
#include <iostream>
#include <string>

#include "app/commands.h"
#include "interfaces/map_subscriber.h"
#include "interfaces/ros_node.h"

namespace monoplane::app {
namespace {

volatile std::sig_atomic_t g_interrupted = 0;
void OnSigint(int) { g_interrupted = 1; }

struct EchoOptions {
  std::string topic;
  int domain_id = 0;
  std::string prefix;
  int count = 0;         // messages to print before exiting; 0 = until interrupted
  double timeout_s = 0;  // give up after this long without a message; 0 = wait forever
};

int Echo(const EchoOptions& o) {
  interfaces::MapSubscriber::Options options;
  options.domain_id = o.domain_id;
  options.topic_prefix = o.prefix;
  std::string error;
  if (!options.IsValid(&error)) {
    std::cerr << "monoplane echo: " << error << "\n";
    return kExitBadInput;
  }
  // ROS 2 sees a subscriber node "/monoplane_echo" (not "/monoplane", which run and serve use).
  interfaces::RosNode::Options node_options;
  node_options.domain_id = o.domain_id;
  node_options.name = "monoplane_echo";
  options.node = interfaces::RosNode::Create(node_options, &error);
  if (!options.node) {
    std::cerr << "monoplane echo: DDS: " << error << "\n";
    return kExitError;
  }
  auto subscriber = interfaces::MapSubscriber::Create(options, o.topic, &error);
  if (!subscriber) {
    std::cerr << "monoplane echo: " << error << "\n";
    return kExitBadInput;
  }
  error.clear();
  std::signal(SIGINT, OnSigint);
  std::fprintf(stderr, "listening on %s (domain %d)\n", subscriber->topic_name().c_str(),
               o.domain_id);
  // Wait in short slices so Ctrl-C is noticed promptly.
  constexpr double kSliceS = 0.2;
  int printed = 0;
  double waited_s = 0.0;
  while (o.count == 0 || printed < o.count) {
    if (g_interrupted) return kExitInterrupted;
    auto message = subscriber->Take(kSliceS, &error);
    if (message) {
      std::printf("%s\n", interfaces::Summarize(*message).c_str());
      std::fflush(stdout);
      ++printed;
      waited_s = 0.0;
      continue;
    }
    if (!error.empty()) {
      std::cerr << "monoplane echo: " << error << "\n";
      return kExitError;
    }
    waited_s += kSliceS;
    if (o.timeout_s > 0 && waited_s >= o.timeout_s) {
      std::cerr << "monoplane echo: no message on " << subscriber->topic_name() << " within "
                << o.timeout_s << " s (" << subscriber->MatchedWriters() << " matched writers)\n";
      return kExitError;
    }
  }
  return kExitOk;
}

}  // namespace

void RegisterEchoCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "echo",
      "Print a summary line per message of a DDS topic (map, map_updates, odom, tf, clock, "
      "monoplane/local_map, moving_obstacles)");
  static EchoOptions options;
  cmd->add_option(
         "TOPIC", options.topic,
         "Topic: map, map_updates, odom, tf, clock, monoplane/local_map, moving_obstacles, or a "
         "full rt/... name")
      ->required();
  cmd->add_option("--domain", options.domain_id, "DDS domain id")->check(CLI::Range(0, 232));
  cmd->add_option("--prefix", options.prefix, "Topic prefix (rt/PREFIX/map)");
  cmd->add_option("--count", options.count, "Exit after N messages (0: run until Ctrl-C)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--timeout", options.timeout_s,
                  "Fail after S seconds without a message (0: wait forever)")
      ->check(CLI::NonNegativeNumber);
  cmd->callback([exit_code] { *exit_code = Echo(options); });
}

}  // namespace monoplane::app
