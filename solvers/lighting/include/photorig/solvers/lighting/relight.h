#pragma once
// Relighting: render an object under new lighting from its normals and albedo,
// or image-based, as a weighted sum of one-light-at-a-time frames.

#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <vector>

namespace photorig::solvers::lighting {

// Each returns a solvers::core::Summary; on kInvalidInput (the reason in its message)
// the output is left untouched. Nothing throws.

// I = albedo / pi * sum_lm A_l L_lm Y_lm(n). coefficients: SH rows (a square
// count) x channels (1 or 3). normals CV_32FC3, albedo CV_32F of their size.
// *image: CV_32F with coefficients.cols() channels (3 channels are stored BGR).
// Pixels with a zero normal are 0.
solvers::core::Summary RenderShLighting(const cv::Mat& normals, const cv::Mat& albedo, const Eigen::MatrixXd& coefficients,
                                  cv::Mat* image);
// I = albedo / pi * sum_k intensity_k max(0, n . d_k); single channel.
// normals CV_32FC3, albedo CV_32FC1 of their size, one intensity per direction.
solvers::core::Summary RenderDirectionalLights(const cv::Mat& normals, const cv::Mat& albedo,
                                         const std::vector<Eigen::Vector3d>& directions,
                                         const std::vector<double>& intensities, cv::Mat* image);
// sum_k weights(k, c) * frames[k] per channel c; frames single-channel, one size, any depth (converted to float).
// weights: frames x (1 or 3); a 3-column weight matrix gives a BGR-stored colour image.
solvers::core::Summary RelightFromFrames(const std::vector<cv::Mat>& frames, const Eigen::MatrixXd& weights, cv::Mat* image);

}  // namespace photorig::solvers::lighting
