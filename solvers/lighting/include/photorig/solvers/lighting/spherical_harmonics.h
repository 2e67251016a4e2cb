#pragma once
// Real spherical harmonics (graphics convention, no Condon-Shortley phase:
// Y_1,-1 ~ y, Y_1,0 ~ z, Y_1,1 ~ x), index l*l + l + m, and the Lambertian
// convolution weights A_l (Ramamoorthi & Hanrahan).

#include <Eigen/Core>

namespace photorig::solvers::lighting {

constexpr int ShCoefficientCount(int band) { return (band + 1) * (band + 1); }

// Fills out[0 .. ShCoefficientCount(band)) with Y_lm(direction); direction unit.
void EvaluateSh(int band, const Eigen::Vector3d& direction, double* out);
Eigen::VectorXd EvaluateSh(int band, const Eigen::Vector3d& direction);

// A_l: irradiance E_lm = A_l L_lm for a clamped-cosine (Lambertian) surface.
double LambertianKernel(int l);

}  // namespace photorig::solvers::lighting
