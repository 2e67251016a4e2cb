#include "adequacy_screen.h"

#include "lane_math.h"
#include "photorig/solvers/ps/stack.h"

namespace photorig::solvers::ps::internal {

PHOTORIG_PS_MULTIVERSION
std::size_t ScreenTile(const std::uint8_t* flags, const std::uint16_t* usable, const float* confidence, int count,
                       const float* threshold, std::uint8_t* needs_refit) {
  int passed = 0;
#pragma omp simd reduction(+ : passed)
  for (int i = 0; i < count; ++i) {
    const bool solved = flags[i] == static_cast<std::uint8_t>(PixelFlag::kSolved);
    const bool pass = confidence[i] >= threshold[usable[i]];
    needs_refit[i] = solved & !pass;
    passed += solved & pass;
  }
  return static_cast<std::size_t>(passed);
}

}  // namespace photorig::solvers::ps::internal
