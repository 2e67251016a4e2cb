#include "photorig/sim/checkerboard.h"

#include "photorig/sim/camera_rays.h"
#include "photorig/solvers/core/summary.h"

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace photorig::sim {
using solvers::core::Refuse;

namespace {

// The reflectance the board shows at (x, y) of its own plane.
double BoardReflectance(const Checkerboard& board, double x_mm, double y_mm) {
  const int squares_x = board.inner_corners_cols + 1, squares_y = board.inner_corners_rows + 1;
  const double u = x_mm / board.square_mm + 0.5 * squares_x, v = y_mm / board.square_mm + 0.5 * squares_y;
  const double border = board.border_mm / board.square_mm;
  if (u < -border || v < -border || u >= squares_x + border || v >= squares_y + border) return board.background;
  if (u < 0.0 || v < 0.0 || u >= squares_x || v >= squares_y) return board.light;
  return (static_cast<int>(u) + static_cast<int>(v)) % 2 == 0 ? board.dark : board.light;
}

}  // namespace

bool Checkerboard::IsValid(std::string* why) const {
  if (inner_corners_cols < 1 || inner_corners_rows < 1) return Refuse(why, "the board needs inner corners");
  if (!(square_mm > 0.0)) return Refuse(why, "square_mm must be > 0");
  if (!(border_mm >= 0.0)) return Refuse(why, "border_mm must be >= 0");
  for (double r : {dark, light, background})
    if (!(r >= 0.0 && r <= 1.0)) return Refuse(why, "reflectances must lie in [0, 1]");
  return true;
}

bool CheckerboardRenderOptions::IsValid(std::string* why) const {
  if (samples_per_axis < 1) return Refuse(why, "samples_per_axis must be >= 1");
  if (bit_depth != 8 && bit_depth != 16) return Refuse(why, "bit_depth must be 8 or 16");
  if (!(noise_sigma >= 0.0)) return Refuse(why, "noise_sigma must be >= 0");
  return true;
}

cv::Mat RenderCheckerboard(const CameraModel& camera, const Checkerboard& board, const Eigen::Isometry3d& board_to_dome,
                           const CheckerboardRenderOptions& options) {
  std::string why;
  if (!camera.IsValid(&why) || !board.IsValid(&why) || !options.IsValid(&why))
    throw std::invalid_argument("RenderCheckerboard: " + why);
  const int n = options.samples_per_axis;
  const Eigen::Isometry3d dome_to_board = board_to_dome.inverse();
  cv::Mat reflectance(camera.height, camera.width, CV_64F);
  std::mt19937_64 random(options.seed);
  std::uniform_real_distribution<double> jitter(0.0, 1.0);
  // A row of pixels at a time: one batch of rays, n x n per pixel, each at a
  // random place in its cell of the pixel. A regular grid would place every
  // edge parallel to the pixels at a multiple of 1 / n px, a bias the corner
  // finder sees; jittered, that error is noise.
  for (int row = 0; row < camera.height; ++row) {
    std::vector<Eigen::Vector2d> points;
    points.reserve(static_cast<std::size_t>(camera.width) * n * n);
    for (int col = 0; col < camera.width; ++col)
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) points.emplace_back(col + (j + jitter(random)) / n, row + (i + jitter(random)) / n);
    std::vector<Eigen::Vector3d> origins, directions;
    CameraRays(camera, points, &origins, &directions);
    for (int col = 0; col < camera.width; ++col) {
      double sum = 0.0;
      for (int s = 0; s < n * n; ++s) {
        const std::size_t k = static_cast<std::size_t>(col) * n * n + s;
        // The ray in the board's frame meets its plane z = 0 ahead of the camera, or nothing.
        const Eigen::Vector3d o = dome_to_board * origins[k], d = dome_to_board.linear() * directions[k];
        const double t = std::abs(d.z()) > 1e-12 ? -o.z() / d.z() : -1.0;
        sum += t > 0.0 ? BoardReflectance(board, o.x() + t * d.x(), o.y() + t * d.y()) : board.background;
      }
      reflectance.at<double>(row, col) = sum / (n * n);
    }
  }
  const double full_scale = options.bit_depth == 8 ? 255.0 : 65535.0;
  if (options.noise_sigma > 0.0) {
    std::normal_distribution<double> noise(0.0, options.noise_sigma);
    for (auto it = reflectance.begin<double>(); it != reflectance.end<double>(); ++it) *it += noise(random);
  }
  cv::Mat image;
  reflectance.convertTo(image, options.bit_depth == 8 ? CV_8U : CV_16U, full_scale);  // saturates at 0 and full scale
  return image;
}

}  // namespace photorig::sim
