#pragma once

// Deterministic random numbers for the simulator. The standard library's
// distributions are implementation-defined (std::normal_distribution differs
// between libstdc++ and libc++), so the simulator draws everything from this
// generator: the same seed gives the same dataset on every platform.

#include <cmath>
#include <cstdint>
#include <string>

namespace ag {

/// SplitMix64 finaliser: a strong 64-bit mix, used to derive seeds.
inline uint64_t MixBits64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// Combines two values into a seed (order matters).
inline uint64_t HashCombine(uint64_t a, uint64_t b) { return MixBits64(a ^ MixBits64(b)); }

/// FNV-1a of a string, to derive per-agent / per-purpose seed streams.
inline uint64_t HashString(const std::string& s) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : s) h = (h ^ c) * 0x100000001b3ULL;
  return MixBits64(h);
}

/// xoshiro256** seeded through SplitMix64; Gaussian by Box-Muller.
class SimRandom {
 public:
  explicit SimRandom(uint64_t seed) {
    uint64_t x = seed;
    for (uint64_t& s : s_) {
      x += 0x9e3779b97f4a7c15ULL;
      s = MixBits64(x);
    }
  }
  /// An independent stream named by `purpose` and an index (frame number, ...).
  SimRandom(uint64_t seed, const std::string& purpose, uint64_t index = 0)
      : SimRandom(HashCombine(HashCombine(seed, HashString(purpose)), index)) {}

  uint64_t NextU64() {
    const uint64_t result = Rotl(s_[1] * 5, 7) * 9;
    const uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = Rotl(s_[3], 45);
    return result;
  }
  /// Uniform in [0, 1) with 53 random bits.
  double Uniform() { return static_cast<double>(NextU64() >> 11) * 0x1.0p-53; }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  /// Uniform integer in [lo, hi] (inclusive).
  int UniformInt(int lo, int hi) {
    return lo + static_cast<int>(NextU64() % static_cast<uint64_t>(hi - lo + 1));
  }
  /// +1 or -1 with equal probability.
  double Sign() { return (NextU64() >> 63) ? 1.0 : -1.0; }
  /// Standard normal.
  double Gaussian() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u1 = Uniform();
    while (u1 <= 0.0) u1 = Uniform();
    const double u2 = Uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(2.0 * M_PI * u2);
    has_spare_ = true;
    return r * std::cos(2.0 * M_PI * u2);
  }

 private:
  static uint64_t Rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  uint64_t s_[4];
  bool has_spare_ = false;
  double spare_ = 0.0;
};

}  // namespace ag
