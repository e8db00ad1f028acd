#pragma once

// Test helper: keeps Cyclone DDS on the loopback interface, without multicast, for every
// participant the test program creates. Included by DDS tests before anything touches DDS; the
// environment is set during static initialisation, before main().

#include <cstdlib>

namespace monoplane::interfaces::testing {

inline constexpr const char* kLoopbackConfig =
    "<CycloneDDS><Domain Id=\"any\">"
    "<General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast></General>"
    // Large grids (a 2000 x 2000 map is 4 MB) burst thousands of fragments; with the kernel's
    // default 208 kB UDP receive buffer they overflow and wait for retransmission.
    "<Internal><SocketReceiveBufferSize max=\"8MB\"/></Internal>"
    "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>100</MaxAutoParticipantIndex>"
    "<Peers><Peer Address=\"127.0.0.1\"/></Peers></Discovery>"
    "</Domain></CycloneDDS>";

inline const bool kLoopbackConfigured = [] {
  return setenv("CYCLONEDDS_URI", kLoopbackConfig, /*overwrite=*/1) == 0;
}();

}  // namespace monoplane::interfaces::testing
