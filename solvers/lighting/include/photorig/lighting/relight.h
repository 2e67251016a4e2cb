#pragma once
// Relighting: render an object under new lighting from its normals and albedo,
// or image-based, as a weighted sum of one-light-at-a-time frames.

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <vector>

namespace photorig::lighting {

// I = albedo / pi * sum_lm A_l L_lm Y_lm(n). coefficients: SH rows x channels (1 or 3).
// Output CV_32F with coefficients.cols() channels (3 channels are stored BGR). Pixels with a zero normal are 0.
cv::Mat RenderShLighting(const cv::Mat& normals, const cv::Mat& albedo, const Eigen::MatrixXd& coefficients);

// I = albedo / pi * sum_k intensity_k max(0, n . d_k); single channel.
cv::Mat RenderDirectionalLights(const cv::Mat& normals, const cv::Mat& albedo,
                                const std::vector<Eigen::Vector3d>& directions,
                                const std::vector<double>& intensities);

// sum_k weights(k, c) * frames[k] per channel c; frames single-channel, any depth (converted to float).
// weights: frames x (1 or 3); a 3-column weight matrix gives a BGR-stored colour image.
cv::Mat RelightFromFrames(const std::vector<cv::Mat>& frames, const Eigen::MatrixXd& weights);

}  // namespace photorig::lighting
