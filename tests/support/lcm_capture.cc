// lcm_capture: test helper that records raw LCM messages of channels matching
// a pattern into numbered files (<out>/<channel>.<n>.bin), one line per
// message in <out>/index.csv (receive time in microseconds as LCM stamps it,
// channel, number, bytes), and exits after --count messages or --timeout
// seconds. Used inside private network
// namespaces only (tests never send LCM traffic outside the machine).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>

int main(int argc, char** argv) {
  CLI::App app{"record raw LCM messages to files (test helper)"};
  std::string pattern = ".*", out_dir, url;
  int count = 1;
  double timeout_s = 30;
  app.add_option("--pattern", pattern, "channel regex");
  app.add_option("--out", out_dir, "output folder")->required();
  app.add_option("--count", count, "stop after this many messages");
  app.add_option("--timeout", timeout_s, "stop after this many seconds");
  app.add_option("--lcm-url", url, "LCM URL");
  CLI11_PARSE(app, argc, argv);
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::fprintf(stderr, "lcm_capture: cannot open LCM\n");
    return 2;
  }
  int received = 0;
  std::map<std::string, int> per_channel;
  std::ofstream index(out_dir + "/index.csv");
  index << "recv_utime,channel,n,bytes\n" << std::flush;
  struct Handler {
    std::string dir;
    int* received;
    std::map<std::string, int>* per_channel;
    std::ofstream* index;
    void On(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
      const int n = (*per_channel)[channel]++;
      std::ofstream(dir + "/" + channel + "." + std::to_string(n) + ".bin", std::ios::binary)
          .write(static_cast<const char*>(rbuf->data), rbuf->data_size);
      *index << rbuf->recv_utime << "," << channel << "," << n << "," << rbuf->data_size << "\n"
             << std::flush;
      ++*received;
    }
  } handler{out_dir, &received, &per_channel, &index};
  // LCM keeps 30 messages per subscription by default; a burst (the parts of a
  // split keyframe) arrives faster than files are written, and none may be lost.
  lcm.subscribe(pattern, &Handler::On, &handler)->setQueueCapacity(std::max(count, 30));
  // Tell the parent we are subscribed (it starts the sender after this).
  std::ofstream(out_dir + "/READY") << "ok\n";
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (received < count && std::chrono::steady_clock::now() < end) lcm.handleTimeout(100);
  std::printf("lcm_capture: %d messages\n", received);
  return received >= count ? 0 : 1;
}
