#pragma once
// log and exp for loops that run one value per SIMD lane (`#pragma omp
// simd`), in double and float. glibc's vector versions are only declared
// under -ffast-math, which would also let the compiler drop the NaN checks
// the solvers rely on; these use nothing but arithmetic and 64-bit integer
// operations, which SSE2, AVX2 and AVX-512 vectorise, and are accurate to a
// few units in the last place. All are always_inline: a call inside a
// `#pragma omp simd` loop would make the loop scalar.

#include <bit>
#include <cstdint>

namespace photorig::solvers::core {

#define PHOTORIG_LANE_INLINE inline __attribute__((always_inline))

// A lane loop's function built for several instruction sets, the best one
// the CPU supports picked at load time (GCC function multi-versioning), so
// that a library stays at the baseline ISA. Such a function must use no
// Eigen, whose types must not cross code built for different ISAs.
#define PHOTORIG_LANE_MULTIVERSION \
  __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))

// c0 x^n + c1 x^(n-1) + ... + cn by Horner's rule, unrolled by the fold (a
// loop here would stop the enclosing lane loop from vectorising).
template <typename T, typename... Coefficients>
PHOTORIG_LANE_INLINE T Horner(T x, T leading, Coefficients... rest) {
  T value = leading;
  ((value = value * x + static_cast<T>(rest)), ...);
  return value;
}

inline constexpr double kLn2Hi = 6.93147180369123816490e-01;  // ln 2 with 20 trailing zero bits
inline constexpr double kLn2Lo = 1.90821492927058770002e-10;  // ln 2 - kLn2Hi

// ln x and 1 / x together, for finite x in [2^-1022, 2^1022]: x = 2^k f with
// f in [sqrt(1/2), sqrt(2)), ln f = 2 atanh(s), s = (f - 1) / (f + 1),
// |s| <= 0.1716, whose odd series to s^19 is exact to double precision. One
// division (the slowest vector operation here) gives both quotients: with
// d = 1 / (f (f + 1)), s = (f - 1) f d and 1 / f = (f + 1) d.
PHOTORIG_LANE_INLINE double LaneLogAndInverse(double x, double* inverse) {
  constexpr std::uint64_t kSqrtHalfBits = 0x3fe6a09e667f3bcdULL;
  constexpr std::uint64_t kBias = 1024ULL << 52;  // keeps the shifted exponent non-negative
  const std::uint64_t bits = std::bit_cast<std::uint64_t>(x);
  const std::uint64_t biased_k = (bits - kSqrtHalfBits + kBias) >> 52;  // k + 1024
  const double f = std::bit_cast<double>(bits - (biased_k << 52) + kBias);
  // k as a double without an int64 -> double conversion (AVX2 has none).
  const double k = std::bit_cast<double>(biased_k | 0x4330000000000000ULL) - (4503599627370496.0 + 1024.0);
  const double d = 1.0 / (f * (f + 1.0));
  const double s = (f - 1.0) * f * d, s2 = s * s;
  *inverse = std::bit_cast<double>((2047ULL - biased_k) << 52) * ((f + 1.0) * d);  // 2^-k / f
  // 2 atanh(s) = s (2 + 2/3 s^2 + 2/5 s^4 + ... + 2/19 s^18).
  const double series = Horner(s2, 2.0 / 19.0, 2.0 / 17.0, 2.0 / 15.0, 2.0 / 13.0, 2.0 / 11.0, 2.0 / 9.0,
                               2.0 / 7.0, 2.0 / 5.0, 2.0 / 3.0, 2.0);
  return k * kLn2Hi + (k * kLn2Lo + s * series);
}

// e^y for y <= 709; below -708 the result is clamped to e^-708 (about 3e-308)
// rather than going subnormal. y = k ln 2 + r with |r| <= ln 2 / 2, e^r by its
// Taylor series to r^13 (truncation below 1e-17), 2^k built in the exponent bits.
PHOTORIG_LANE_INLINE double LaneExp(double y) {
  constexpr double kRound = 6755399441055744.0;  // 1.5 * 2^52: adding it rounds to an integer
  const double clamped = y < -708.0 ? -708.0 : y;
  const double t = clamped * 1.4426950408889634 + kRound;
  const double k = t - kRound;
  const double r = clamped - k * kLn2Hi - k * kLn2Lo;
  const double p = Horner(r, 1.0 / 6227020800.0, 1.0 / 479001600.0, 1.0 / 39916800.0, 1.0 / 3628800.0,
                          1.0 / 362880.0, 1.0 / 40320.0, 1.0 / 5040.0, 1.0 / 720.0, 1.0 / 120.0, 1.0 / 24.0,
                          1.0 / 6.0, 0.5, 1.0, 1.0);
  // The low bits of t hold k (two's complement, wrapped): 2^k = (k + 1023) << 52.
  const std::uint64_t k_bits = std::bit_cast<std::uint64_t>(t) - std::bit_cast<std::uint64_t>(kRound);
  return p * std::bit_cast<double>((k_bits + 1023) << 52);
}

// The same two in float, for the Blinn-Phong fit's evaluation: ln x and 1 / x
// for finite x in [2^-126, 2^126], the series to s^9 (truncation below 1e-9);
// e^y for y <= 88, clamped below at e^-80 so that products with the result
// stay clear of subnormals, Taylor series to r^7 (truncation below 1e-8).
// Both are accurate to a few float ulp.
inline constexpr float kLn2HiF = 0.693145751953125f;   // ln 2 with 9 trailing zero bits
inline constexpr float kLn2LoF = 1.428606765330187e-06f;  // ln 2 - kLn2HiF

PHOTORIG_LANE_INLINE float LaneLogAndInverse(float x, float* inverse) {
  constexpr std::uint32_t kSqrtHalfBits = 0x3f3504f3U;
  constexpr std::uint32_t kBias = 128U << 23;  // keeps the shifted exponent non-negative
  const std::uint32_t bits = std::bit_cast<std::uint32_t>(x);
  const std::uint32_t biased_k = (bits - kSqrtHalfBits + kBias) >> 23;  // k + 128
  const float f = std::bit_cast<float>(bits - (biased_k << 23) + kBias);
  const float k = static_cast<float>(static_cast<std::int32_t>(biased_k) - 128);
  const float d = 1.0f / (f * (f + 1.0f));
  const float s = (f - 1.0f) * f * d, s2 = s * s;
  *inverse = std::bit_cast<float>((255U - biased_k) << 23) * ((f + 1.0f) * d);  // 2^-k / f
  const float series = Horner(s2, 2.0f / 9.0f, 2.0f / 7.0f, 2.0f / 5.0f, 2.0f / 3.0f, 2.0f);
  return k * kLn2HiF + (k * kLn2LoF + s * series);
}

PHOTORIG_LANE_INLINE float LaneExp(float y) {
  constexpr float kRound = 12582912.0f;  // 1.5 * 2^23: adding it rounds to an integer
  const float clamped = y < -80.0f ? -80.0f : y;
  const float t = clamped * 1.44269504f + kRound;
  const float k = t - kRound;
  const float r = clamped - k * kLn2HiF - k * kLn2LoF;
  const float p = Horner(r, 1.0f / 5040.0f, 1.0f / 720.0f, 1.0f / 120.0f, 1.0f / 24.0f, 1.0f / 6.0f, 0.5f, 1.0f, 1.0f);
  // The low bits of t hold k (two's complement, wrapped): 2^k = (k + 127) << 23.
  const std::uint32_t k_bits = std::bit_cast<std::uint32_t>(t) - std::bit_cast<std::uint32_t>(kRound);
  return p * std::bit_cast<float>((k_bits + 127U) << 23);
}

}  // namespace photorig::solvers::core
