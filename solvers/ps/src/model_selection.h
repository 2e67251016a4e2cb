#pragma once
// Model selection: when a fit explains a pixel (chi-square against the noise).

#include <vector>

namespace photorig::ps::internal {

// Quantile p of the chi-square distribution for 0..max_dof degrees of
// freedom, by Wilson-Hilferty: accurate to a few per cent for dof >= 3, plenty
// for a test threshold. Entry 0 is 0.
std::vector<double> ChiSquareQuantiles(int max_dof, double p);

}  // namespace photorig::ps::internal
