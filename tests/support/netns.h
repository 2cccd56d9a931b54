#pragma once

#include <string>

namespace ag::test {

/// True when this machine lets an unprivileged process create a network
/// namespace of its own (`unshare -rn`). Tests that run LCM over UDP need it
/// and skip with a message otherwise.
bool CanCreateNetworkNamespace();

/// Runs `script` with sh inside a fresh network namespace that has only
/// loopback, with the multicast route LCM needs on it, so no datagram can
/// leave the machine. Returns the exit status; output goes to `log_path`.
int RunInPrivateNetwork(const std::string& script, const std::string& log_path);

/// The LCM URL tests use inside such a namespace (ttl=0: never routed).
inline const char* kTestLcmUrl = "udpm://239.255.76.67:7667?ttl=0";

}  // namespace ag::test
