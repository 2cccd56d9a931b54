// place_db_bench: insertion and retrieval time, recall against exact search
// and memory of the place database (paper, Sec. "Database Maintenance and
// Retrieval": 0.84 ms per retrieval), printed as a table.
//
//   place_db_bench                          # 1k, 10k, 100k entries, default options
//   place_db_bench --sizes 10000 --ef 16,32,64,128
//
// Data: "trajectory" descriptors (SyntheticPlaces along SyntheticFlight, the
// realistic case) and uniform random unit vectors (the worst case). Queries
// are UGV-like views near the flown places (trajectory) or random vectors
// (uniform). Exact reference: FAISS IndexFlatIP, one thread.

#include <faiss/IndexFlat.h>
#include <omp.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <random>
#include <string>
#include <vector>

#include "common/core/cpu_time.h"
#include "ground_server/place_db/place_db.h"
#include "ground_server/place_db/synthetic_places.h"

namespace ag {
namespace {

using Clock = std::chrono::steady_clock;

double Ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

struct Percentiles {
  double median = 0;
  double p95 = 0;
};

Percentiles Summarise(std::vector<double> ms) {
  if (ms.empty()) return {};
  std::sort(ms.begin(), ms.end());
  return {ms[ms.size() / 2], ms[std::min(ms.size() - 1, ms.size() * 95 / 100)]};
}

struct Dataset {
  std::string name;
  std::vector<AirKeyframe> keyframes;
  std::vector<std::vector<float>> queries;
};

Dataset Trajectory(int n, int queries, uint32_t seed) {
  Dataset d;
  d.name = "trajectory";
  const SyntheticPlaces places({});
  // Keyframes every 2 m over a square sized so that long flights revisit.
  const double area_m = n >= 50000 ? 2000.0 : 500.0;
  const auto flight = SyntheticFlight(n, 2.0, area_m, seed);
  std::mt19937 rng(seed);
  for (int i = 0; i < n; ++i) {
    const Pose& T = flight[static_cast<size_t>(i)];
    d.keyframes.push_back(
        SyntheticKeyframe("uav1", i, T, places.Descriptor(T, 0.3, rng), 0, 0, rng));
  }
  std::uniform_int_distribution<size_t> pick(0, flight.size() - 1);
  std::normal_distribution<double> offset_m(0.0, 3.0);
  std::normal_distribution<double> offset_rad(0.0, 0.3);
  for (int i = 0; i < queries; ++i) {
    Pose T = flight[pick(rng)];
    T.translation() += Eigen::Vector3d(offset_m(rng), offset_m(rng), 0);
    T.linear() = RotZ(offset_rad(rng)) * T.linear();
    d.queries.push_back(places.Descriptor(T, 0.5, rng));
  }
  return d;
}

Dataset Uniform(int n, int queries, uint32_t seed) {
  Dataset d;
  d.name = "uniform";
  std::mt19937 rng(seed);
  for (int i = 0; i < n; ++i) {
    d.keyframes.push_back(
        SyntheticKeyframe("uav1", i, Pose::Identity(), RandomUnitVector(512, rng), 0, 0, rng));
  }
  for (int i = 0; i < queries; ++i) d.queries.push_back(RandomUnitVector(512, rng));
  return d;
}

void Run(const Dataset& data, PlaceDb::Options options, const std::vector<int>& efs,
         int extra_at_cap) {
  const int n = static_cast<int>(data.keyframes.size());
  options.max_keyframes = std::max<int64_t>(n, 1);
  PlaceDb db(options);

  std::vector<double> insert_ms;
  for (const AirKeyframe& kf : data.keyframes) {
    const auto t0 = Clock::now();
    const auto r = db.Insert(kf);
    insert_ms.push_back(Ms(Clock::now() - t0));
    if (!r.success) std::fprintf(stderr, "insert failed: %s\n", r.reason.c_str());
  }
  const Percentiles insert = Summarise(insert_ms);
  const PlaceDb::Stats stats = db.GetStats();

  // Exact top-5 of every query in one batch (all cores), then the time of a
  // single exact query on one thread, like a place query in the server.
  faiss::IndexFlatIP exact(512);
  for (const AirKeyframe& kf : data.keyframes) exact.add(1, kf.global_descriptor.data());
  const auto nq = static_cast<faiss::Index::idx_t>(data.queries.size());
  std::vector<float> query_data;
  for (const auto& q : data.queries) query_data.insert(query_data.end(), q.begin(), q.end());
  std::vector<float> sims(static_cast<size_t>(nq) * 5);
  std::vector<faiss::Index::idx_t> rows(static_cast<size_t>(nq) * 5);
  exact.search(nq, query_data.data(), 5, sims.data(), rows.data());
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  std::vector<double> exact_ms;
  std::vector<float> one_sim(5);
  std::vector<faiss::Index::idx_t> one_row(5);
  for (faiss::Index::idx_t q = 0; q < std::min<faiss::Index::idx_t>(nq, 100); ++q) {
    const auto t0 = Clock::now();
    exact.search(1, data.queries[static_cast<size_t>(q)].data(), 5, one_sim.data(), one_row.data());
    exact_ms.push_back(Ms(Clock::now() - t0));
  }
  omp_set_num_threads(threads);
  const Percentiles brute = Summarise(exact_ms);

  for (int ef : efs) {
    db.SetEfSearch(ef);
    std::vector<double> query_ms;
    std::vector<double> query_cpu_ms;
    double at1 = 0;
    double at5 = 0;
    for (size_t q = 0; q < data.queries.size(); ++q) {
      const double c0 = ThreadCpuMs();
      const auto t0 = Clock::now();
      const auto r = db.Query(data.queries[q], 5);
      query_ms.push_back(Ms(Clock::now() - t0));
      query_cpu_ms.push_back(ThreadCpuMs() - c0);
      if (r.matches.empty()) continue;
      // Ids are insertion order = FAISS rows (no eviction during the build).
      at1 += r.matches[0].entry.id == rows[q * 5] ||
             std::abs(r.matches[0].similarity - sims[q * 5]) <= 1e-6F;
      int common = 0;
      for (const auto& m : r.matches) {
        for (size_t j = 0; j < 5; ++j) common += m.entry.id == rows[q * 5 + j];
      }
      at5 += common / 5.0;
    }
    const Percentiles query = Summarise(query_ms);
    const Percentiles query_cpu = Summarise(query_cpu_ms);
    std::printf("| %-10s | %6d | %7.3f | %7.3f | %4d | %7.4f | %7.4f | %7.4f | %6.4f | %6.4f | ",
                data.name.c_str(), n, insert.median, insert.p95, ef, query.median, query.p95,
                query_cpu.median, at1 / static_cast<double>(data.queries.size()),
                at5 / static_cast<double>(data.queries.size()));
    std::printf("%7.3f | %6.0f | %7.1f |\n", brute.median,
                static_cast<double>(stats.index_bytes) / n, stats.TotalBytes() / 1e6);
    std::fflush(stdout);
  }
  db.SetEfSearch(options.ef_search);

  // Steady state at the cap: every insert evicts one keyframe and refills
  // its graph slot (hnswlib updatePoint), which costs more than appending.
  if (extra_at_cap > 0 && data.name == "trajectory") {
    const SyntheticPlaces places({});
    const auto flight = SyntheticFlight(extra_at_cap, 2.0, 500.0, 77);
    std::mt19937 rng(77);
    std::vector<double> cap_ms;
    for (int i = 0; i < extra_at_cap; ++i) {
      const Pose& T = flight[static_cast<size_t>(i)];
      AirKeyframe kf =
          SyntheticKeyframe("uav1", n + i, T, places.Descriptor(T, 0.3, rng), 0, 0, rng);
      const auto t0 = Clock::now();
      db.Insert(std::move(kf));
      cap_ms.push_back(Ms(Clock::now() - t0));
    }
    const Percentiles at_cap = Summarise(cap_ms);
    std::printf(
        "|   at cap %-6d: insert with eviction + slot refill, median %.3f ms, p95 %.3f ms (%d "
        "inserts) |\n",
        n, at_cap.median, at_cap.p95, extra_at_cap);
  }
}

}  // namespace
}  // namespace ag

int main(int argc, char** argv) {
  try {
    CLI::App app("Place database benchmark: HNSW vs exact search, time, recall, memory");
    std::vector<int> sizes = {1000, 10000, 100000};
    std::vector<int> efs = {ag::PlaceDb::Options().ef_search};
    int queries = 1000;
    int uniform_max = 10000;
    int at_cap = 1000;
    ag::PlaceDb::Options options;
    app.add_option("--sizes", sizes, "database sizes (entries)")->delimiter(',');
    app.add_option("--ef", efs, "ef_search values")->delimiter(',');
    app.add_option("--queries", queries, "queries per size")->check(CLI::PositiveNumber);
    app.add_option("--uniform-max", uniform_max,
                   "largest size for the uniform random data (0: none)");
    app.add_option("--at-cap", at_cap, "inserts measured at the cap after the build (0: none)");
    app.add_option("--m", options.hnsw_m, "HNSW M");
    app.add_option("--ef-construction", options.ef_construction, "HNSW ef_construction");
    CLI11_PARSE(app, argc, argv);

    const ag::PlaceDb::Options defaults;
    std::printf(
        "place_db_bench: M %d, ef_construction %d, ef_search %d by default, dim %d; k = 5\n",
        options.hnsw_m, options.ef_construction, defaults.ef_search, defaults.dim);
    std::printf(
        "| data       |      N | ins med | ins p95 |   ef | qry med | qry p95 | qry cpu |  rec@1 | "
        " rec@5 | exact   | idx B/ | tot MB  |\n");
    std::printf(
        "|            |        |   ms    |   ms    |      |   ms    |   ms    | med ms  |        | "
        "       | med ms  | entry  |         |\n");
    for (int n : sizes) {
      ag::Run(ag::Trajectory(n, queries, 11), options, efs, std::min(at_cap, n));
    }
    for (int n : sizes) {
      if (n <= uniform_max) ag::Run(ag::Uniform(n, queries, 12), options, efs, 0);
    }
    std::mt19937 rng(1);
    for (int keypoints : {512, 1024}) {
      const ag::AirKeyframe typical = ag::SyntheticKeyframe(
          "uav1", 0, ag::Pose::Identity(), ag::RandomUnitVector(512, rng), keypoints, 64, rng);
      const int64_t bytes = ag::KeyframeBytes(typical);
      const int64_t held = std::min(defaults.max_bytes / bytes, defaults.max_keyframes);
      std::printf(
          "A retained keyframe of %d keypoints (64-D float descriptors, 512-D global): %.1f KB; "
          "the default caps (max_bytes %.2g B, max_keyframes %lld) hold %lld of them, %.1f h of "
          "one UAV at 1 keyframe/s.\n",
          keypoints, bytes / 1e3, static_cast<double>(defaults.max_bytes),
          static_cast<long long>(defaults.max_keyframes), static_cast<long long>(held),
          static_cast<double>(held) / 3600.0);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "place_db_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
