#include "tests/support/netns.h"

#include <sys/wait.h>

#include <cstdlib>

namespace ag::test {

bool CanCreateNetworkNamespace() {
  return std::system("unshare -rn sh -c 'ip link set lo up' >/dev/null 2>&1") == 0;
}

int RunInPrivateNetwork(const std::string& script, const std::string& log_path) {
  const std::string command =
      "unshare -rn sh -c 'ip link set lo up && ip route add 224.0.0.0/4 dev lo && " + script +
      "' > " + log_path + " 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace ag::test
