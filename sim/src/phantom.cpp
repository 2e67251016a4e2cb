#include "photorig/sim/phantom.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace photorig::sim {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Maps a point of the phantom's frame into the ellipsoid's, where it is the unit ball.
struct LocalFrame {
  Eigen::Matrix3d to_unit;  // diag(1/a, 1/b, 1/c) * R
  Eigen::Vector3d centre;
};

LocalFrame Frame(const Ellipsoid& e, double scale_mm) {
  const double deg = std::numbers::pi / 180.0;
  // z-x-z Euler rotation into the ellipsoid's axes.
  const Eigen::Matrix3d rotation = (Eigen::AngleAxisd(e.phi_deg * deg, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(e.theta_deg * deg, Eigen::Vector3d::UnitX()) *
                                    Eigen::AngleAxisd(e.psi_deg * deg, Eigen::Vector3d::UnitZ()))
                                       .toRotationMatrix();
  const Eigen::Vector3d inverse_axes(1.0 / (e.a * scale_mm), 1.0 / (e.b * scale_mm), 1.0 / (e.c * scale_mm));
  return {inverse_axes.asDiagonal() * rotation.transpose(), scale_mm * Eigen::Vector3d(e.x0, e.y0, e.z0)};
}

// The chord through the unit ball of frame f along (origin, direction), in mm.
double Chord(const LocalFrame& f, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) {
  // |o' + t d'|^2 = 1 in the ellipsoid's unit-ball frame; t is in mm along the ray.
  const Eigen::Vector3d o = f.to_unit * (origin - f.centre), d = f.to_unit * direction;
  const double qa = d.squaredNorm(), qb = 2.0 * o.dot(d), qc = o.squaredNorm() - 1.0;
  const double disc = qb * qb - 4.0 * qa * qc;
  if (qa <= 0.0 || disc <= 0.0) return 0.0;
  return std::sqrt(disc) / qa;
}

}  // namespace

Phantom Phantom::SheppLogan3d(double half_extent_mm, double sigma_per_mm) {
  Phantom p;
  p.half_extent_mm = half_extent_mm;
  p.sigma_per_mm = sigma_per_mm;
  //          A      a      b      c      x0     y0       z0    phi theta psi
  p.ellipsoids = {{1.0, .6900, .920, .810, 0, 0, 0, 0, 0, 0},
                  {-.8, .6624, .874, .780, 0, -.0184, 0, 0, 0, 0},
                  {-.2, .1100, .310, .220, .22, 0, 0, -18, 0, 10},
                  {-.2, .1600, .410, .280, -.22, 0, 0, 18, 0, 10},
                  {.1, .2100, .250, .410, 0, .35, -.15, 0, 0, 0},
                  {.1, .0460, .046, .050, 0, .1, .25, 0, 0, 0},
                  {.1, .0460, .046, .050, 0, -.1, .25, 0, 0, 0},
                  {.1, .0460, .023, .050, -.08, -.605, 0, 0, 0, 0},
                  {.1, .0230, .023, .020, 0, -.606, 0, 0, 0, 0},
                  {.1, .0230, .046, .020, .06, -.605, 0, 0, 0, 0}};
  return p;
}

Phantom Phantom::SheppLogan2d(double half_extent_mm, double sigma_per_mm) {
  Phantom p;
  p.half_extent_mm = half_extent_mm;
  p.sigma_per_mm = sigma_per_mm;
  //          A      a      b    c     x0    y0    z0  phi
  p.ellipsoids = {{1.0, .6900, .9200, kInf, 0, 0, 0, 0, 0, 0},
                  {-.8, .6624, .8740, kInf, 0, -.0184, 0, 0, 0, 0},
                  {-.2, .1100, .3100, kInf, .22, 0, 0, -18, 0, 0},
                  {-.2, .1600, .4100, kInf, -.22, 0, 0, 18, 0, 0},
                  {.1, .2100, .2500, kInf, 0, .35, 0, 0, 0, 0},
                  {.1, .0460, .0460, kInf, 0, .1, 0, 0, 0, 0},
                  {.1, .0460, .0460, kInf, 0, -.1, 0, 0, 0, 0},
                  {.1, .0460, .0230, kInf, -.08, -.605, 0, 0, 0, 0},
                  {.1, .0230, .0230, kInf, 0, -.606, 0, 0, 0, 0},
                  {.1, .0230, .0460, kInf, .06, -.605, 0, 0, 0, 0}};
  return p;
}

PhantomSampler::PhantomSampler(const Phantom& phantom) : sigma_per_mm_(phantom.sigma_per_mm) {
  frames_.reserve(phantom.ellipsoids.size());
  for (const Ellipsoid& e : phantom.ellipsoids) {
    const LocalFrame f = Frame(e, phantom.half_extent_mm);
    frames_.push_back({f.to_unit, f.centre, e.amplitude});
  }
}

double PhantomSampler::Sigma(const Eigen::Vector3d& point_mm) const {
  double sum = 0.0;
  for (const EllipsoidFrame& f : frames_)
    if ((f.to_unit * (point_mm - f.centre)).squaredNorm() <= 1.0) sum += f.amplitude;
  return sum * sigma_per_mm_;
}

double PhantomSampler::LineIntegral(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const {
  double sum = 0.0;
  for (const EllipsoidFrame& f : frames_) sum += f.amplitude * Chord({f.to_unit, f.centre}, origin, direction);
  return sum * sigma_per_mm_;
}

double Phantom::Sigma(const Eigen::Vector3d& point_mm) const { return PhantomSampler(*this).Sigma(point_mm); }

double Phantom::LineIntegral(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const {
  return PhantomSampler(*this).LineIntegral(origin, direction);
}

std::vector<float> Phantom::Rasterise(const solvers::tomography::VolumeGrid& grid, int supersample) const {
  std::vector<float> sigma(static_cast<std::size_t>(grid.voxels()));
  const PhantomSampler sampler(*this);
  const int sz = grid.nz == 1 ? 1 : supersample;
#pragma omp parallel for schedule(dynamic, 1)
  for (int k = 0; k < grid.nz; ++k)
    for (int j = 0; j < grid.ny; ++j)
      for (int i = 0; i < grid.nx; ++i) {
        const Eigen::Vector3d centre = grid.VoxelCentre(i, j, k);
        double sum = 0.0;
        for (int c = 0; c < sz; ++c)
          for (int b = 0; b < supersample; ++b)
            for (int a = 0; a < supersample; ++a) {
              const Eigen::Vector3d offset((a + 0.5) / supersample - 0.5, (b + 0.5) / supersample - 0.5,
                                           sz == 1 ? 0.0 : (c + 0.5) / sz - 0.5);
              sum += sampler.Sigma(centre + grid.voxel_mm * offset);
            }
        sigma[static_cast<std::size_t>(grid.Index(i, j, k))] =
            static_cast<float>(sum / (supersample * supersample * sz));
      }
  return sigma;
}

std::vector<float> ProjectPhantom(const Phantom& phantom, const solvers::tomography::Geometry& geometry, int supersample) {
  std::vector<float> b(static_cast<std::size_t>(geometry.rays()));
  const int s = std::max(1, supersample);
  // Sub-rays of a pixel: the same geometry with a finer pitch, whose pixel
  // (s col + a, s row + c) lies inside pixel (col, row).
  // A one-row detector is a line through a slice: its sub-rays stay in the slice's plane.
  const int sub_rows = geometry.detector_rows == 1 ? 1 : s;
  solvers::tomography::Geometry fine = geometry;
  fine.detector_cols *= s;
  fine.detector_rows *= sub_rows;
  fine.pixel_mm /= s;
  // Each ellipsoid's frame once, not once a ray (a scan of one view is a frame of the simulated rig).
  std::vector<LocalFrame> frames;
  for (const Ellipsoid& e : phantom.ellipsoids) frames.push_back(Frame(e, phantom.half_extent_mm));
#pragma omp parallel for collapse(2) schedule(dynamic, 1)
  for (int view = 0; view < geometry.views(); ++view)
    for (int row = 0; row < geometry.detector_rows; ++row)
      for (int col = 0; col < geometry.detector_cols; ++col) {
        double sum = 0.0;
        Eigen::Vector3d origin, direction;
        for (int c = 0; c < sub_rows; ++c)
          for (int a = 0; a < s; ++a) {
            fine.Ray(view, sub_rows * row + c, s * col + a, &origin, &direction);
            for (std::size_t k = 0; k < frames.size(); ++k)
              sum += phantom.ellipsoids[k].amplitude * phantom.sigma_per_mm * Chord(frames[k], origin, direction);
          }
        b[static_cast<std::size_t>(geometry.RayIndex(view, row, col))] = static_cast<float>(sum / (sub_rows * s));
      }
  return b;
}

TomographyScan ScanPhantom(const Phantom& phantom, const solvers::tomography::Geometry& geometry,
                           const TomographyScanOptions& options) {
  TomographyScan scan;
  const int rows = geometry.detector_rows, cols = geometry.detector_cols;
  const std::vector<float> tau = ProjectPhantom(phantom, geometry, options.supersample);
  const cv::Mat flat(rows, cols, CV_32F, cv::Scalar(options.backlight_radiance));
  const cv::Mat dark = cv::Mat::zeros(rows, cols, CV_32F);
  // Frame indices keep every frame's noise its own: darks, then flats, then views.
  std::uint64_t frame = 0;
  for (int i = 0; i < options.darks; ++i)
    scan.darks.push_back(ExposeFrame(options.sensor, dark, options.exposure_us, options.gain_db, options.seed, frame++));
  for (int i = 0; i < options.flats; ++i)
    scan.flats.push_back(ExposeFrame(options.sensor, flat, options.exposure_us, options.gain_db, options.seed, frame++));
  for (int view = 0; view < geometry.views(); ++view) {
    cv::Mat radiance(rows, cols, CV_32F);
    for (int r = 0; r < rows; ++r)
      for (int c = 0; c < cols; ++c)
        radiance.at<float>(r, c) = static_cast<float>(
            options.backlight_radiance * std::exp(-tau[static_cast<std::size_t>(geometry.RayIndex(view, r, c))]));
    scan.projections.push_back(
        ExposeFrame(options.sensor, radiance, options.exposure_us, options.gain_db, options.seed, frame++));
  }
  return scan;
}

}  // namespace photorig::sim
