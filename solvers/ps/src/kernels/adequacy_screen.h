#pragma once
// The screen of `auto`: which pixels of a tile the Lambertian pass's own
// confidence already shows to be explained (ModelLadder::ScreenThresholds).

#include <cstddef>
#include <cstdint>

namespace photorig::solvers::ps::internal {

// Marks the solved pixels of a tile whose Lambertian confidence is below
// threshold[usable samples] (they need a closer look); returns how many
// solved pixels pass.
std::size_t ScreenTile(const std::uint8_t* flags, const std::uint16_t* usable, const float* confidence, int count,
                       const float* threshold, std::uint8_t* needs_refit);

}  // namespace photorig::solvers::ps::internal
