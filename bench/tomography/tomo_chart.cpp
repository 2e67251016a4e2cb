// Accuracy and speed of ART, SIRT, CGLS and SART (with and without total
// variation) on the 2D Shepp-Logan slice
// (parallel beam over 180 degrees, exact ellipse line integrals, ground truth
// rasterised with 4 x 4 samples per pixel), for scripts/chart-tomography.sh.
//
//   photorig-tomo-chart OUT_DIR [n] [views]
//   photorig-tomo-chart OUT_DIR n views --problem-only   the peer's files alone
//   photorig-tomo-chart OUT_DIR n views --solve VARIANT  one stopped solve (art, sirt, cgls, sart, sart-tv) of the noisy
//        sinogram read back from OUT_DIR, written as tomo_slice_METHOD.nrrd: the
//        whole-process run timed against the peer's
//
// writes to OUT_DIR:
//   tomo_iterations.csv  method,noise,iteration,elapsed_ms,error,residual,stopped
//                        (every iteration, processor time of the solve; stopped = 1 where
//                        the discrepancy rule stops)
//   tomo_views.csv       method,noise,views,iterations,error  (the automatically stopped solve)
//   tomo_slice_{truth,sinogram_clean,sinogram_noisy}.f32 and tomo_slice.txt: the problem for the
//                        scikit-image peer (raw little-endian float32; sinogram views x columns)
//   tomo_slice_{truth,art,sirt,cgls,sart,sart-tv}.png: the slice and the stopped reconstructions of the
//                        noisy data
// Error: relative L2 inside the reconstruction circle. Noise: Gaussian, 1 % of b's peak.

#include "photorig/sim/phantom.h"
#include "photorig/solvers/tomography/nrrd.h"
#include "photorig/solvers/tomography/projector.h"
#include "photorig/solvers/tomography/reconstruct.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <ctime>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <random>
#include <string>

namespace tomo = photorig::solvers::tomography;

namespace {

// Joseph's interpolating rows: on this sharp-edged phantom its error minimum
// is lower than Siddon's exact lengths (0.077 against 0.107 noise-free).
tomo::ProjectorOptions ProjectorChoice() {
  tomo::ProjectorOptions options;
  options.interpolation = tomo::Interpolation::kJoseph;
  return options;
}

// Processor time of this process, ms: the machine the figures come from is
// shared, and wall time there measures the neighbours.
double CpuMs() { return 1e3 * static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

struct Slice {
  tomo::VolumeGrid grid;
  tomo::Geometry geometry;
  Eigen::VectorXf truth, peer_truth;
  std::vector<std::uint8_t> inside;
  tomo::Absorbance clean, noisy;
  double noise_sigma = 0.0;
  std::unique_ptr<tomo::Projector> projector;

  Slice(int n, int views) : grid{n, n, 1, 32.0 / n} {
    const auto phantom = photorig::sim::Phantom::SheppLogan2d(16.0, 0.1);
    geometry.detector_cols = n;
    geometry.detector_rows = 1;
    geometry.pixel_mm = grid.voxel_mm;
    geometry.angles_rad = tomo::EvenAngles(views, 180.0);
    // The axis on detector bin n/2 (flipped: see the peer script), where
    // scikit-image puts it; ours is then half a pixel off the detector's centre.
    geometry.cor_offset_mm = -0.5 * geometry.pixel_mm;
    const std::vector<float> raster = phantom.Rasterise(grid, 4);
    truth = Eigen::Map<const Eigen::VectorXf>(raster.data(), static_cast<Eigen::Index>(raster.size()));
    inside.resize(raster.size());
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        inside[grid.Index(i, j, 0)] = grid.VoxelCentre(i, j, 0).head<2>().norm() < 0.5 * n * grid.voxel_mm;
    const std::vector<float> b = photorig::sim::ProjectPhantom(phantom, geometry);
    clean.b = Eigen::Map<const Eigen::VectorXf>(b.data(), static_cast<Eigen::Index>(b.size()));
    noise_sigma = 0.01 * clean.b.maxCoeff();
    noisy = clean;
    std::mt19937 rng(2026);
    std::normal_distribution<float> gauss(0.0f, static_cast<float>(noise_sigma));
    for (auto& v : noisy.b) v += gauss(rng);
    tomo::MakeProjector(grid, geometry, ProjectorChoice(), &projector);
    // scikit-image's pixel grid: its centre pixel (n/2, n/2) on the axis, image
    // rows downwards from +y; 4 x 4 samples per pixel as for ours.
    const photorig::sim::PhantomSampler sampler(phantom);
    peer_truth.resize(n * n);
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        double sum = 0.0;
        for (int b = 0; b < 4; ++b)
          for (int a = 0; a < 4; ++a)
            sum += sampler.Sigma(grid.voxel_mm * Eigen::Vector3d(c - 0.5 * n + (a + 0.5) / 4 - 0.5,
                                                                 0.5 * n - r + (b + 0.5) / 4 - 0.5, 0.0));
        peer_truth[r * n + c] = static_cast<float>(sum / 16);
      }
  }

  double Error(const Eigen::VectorXf& x) const {
    double diff = 0.0, norm = 0.0;
    for (std::int64_t i = 0; i < x.size(); ++i)
      if (inside[i]) {
        diff += (x[i] - truth[i]) * (x[i] - truth[i]);
        norm += truth[i] * truth[i];
      }
    return std::sqrt(diff / norm);
  }
};

void WriteFloats(const std::string& path, const Eigen::VectorXf& v) {
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(v.data()), sizeof(float) * v.size());
}

void WritePng(const std::string& path, const tomo::VolumeGrid& grid, const Eigen::VectorXf& x, double max_sigma) {
  cv::Mat image(grid.ny, grid.nx, CV_8U);
  // Row 0 of the image is the top of the slice (+y).
  for (int j = 0; j < grid.ny; ++j)
    for (int i = 0; i < grid.nx; ++i)
      image.at<std::uint8_t>(grid.ny - 1 - j, i) =
          cv::saturate_cast<std::uint8_t>(255.0 * x[grid.Index(i, j, 0)] / max_sigma);
  cv::imwrite(path, image);
}

// The problem for the peer.
void WriteProblem(const std::string& out, const Slice& slice, int n, int views) {
  WriteFloats(out + "/tomo_slice_truth.f32", slice.truth);
  WriteFloats(out + "/tomo_slice_peer_truth.f32", slice.peer_truth);
  WriteFloats(out + "/tomo_slice_sinogram_clean.f32", slice.clean.b);
  WriteFloats(out + "/tomo_slice_sinogram_noisy.f32", slice.noisy.b);
  std::ofstream(out + "/tomo_slice.txt") << "n " << n << "\nviews " << views << "\nspan_deg 180\npixel_mm "
                                         << slice.grid.voxel_mm << "\nnoise_sigma " << slice.noise_sigma << '\n';
  WritePng(out + "/tomo_slice_truth.png", slice.grid, slice.truth, 0.1);
}

// A method as charted: SART with and without total variation.
struct Variant {
  const char* name;
  tomo::Method method;
  bool total_variation;
};

constexpr Variant kVariants[] = {{"art", tomo::Method::kArt, false},
                                 {"sirt", tomo::Method::kSirt, false},
                                 {"cgls", tomo::Method::kCgls, false},
                                 {"sart", tomo::Method::kSart, false},
                                 {"sart-tv", tomo::Method::kSart, true}};

const Variant* FindVariant(const std::string& name) {
  for (const Variant& v : kVariants)
    if (name == v.name) return &v;
  return nullptr;
}

int Iterations(tomo::Method method) {
  switch (method) {
    case tomo::Method::kArt: return 30;
    case tomo::Method::kSart: return 40;
    case tomo::Method::kSirt: return 400;
    case tomo::Method::kCgls: return 60;
  }
  return 0;
}

tomo::ReconstructOptions Options(const Variant& variant) {
  tomo::ReconstructOptions options;
  options.method = variant.method;
  options.total_variation = variant.total_variation;
  options.max_iterations = Iterations(variant.method);
  // As `photorig solve tomography`: the pixel model's own error (|W truth - b|
  // is 0.8 of the 1 % noise's norm here) adds to the noise (docs/tomography.md).
  options.discrepancy_factor = 1.2;
  return options;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << "usage: photorig-tomo-chart OUT_DIR [n] [views]\n";
    return 2;
  }
  const std::string out = argv[1];
  const int n = argc > 2 ? std::stoi(argv[2]) : 128;
  const int views = argc > 3 ? std::stoi(argv[3]) : 64;
  const std::string mode = argc > 4 ? argv[4] : "";
  if (mode == "--solve" && argc > 5) {
    // Only what a user's run does: the geometry, the sinogram from disk, W, the stopped solve.
    const Variant* variant = FindVariant(argv[5]);
    if (!variant) return 2;
    tomo::VolumeGrid grid{n, n, 1, 32.0 / n};
    tomo::Geometry geometry;
    geometry.detector_cols = n;
    geometry.detector_rows = 1;
    geometry.pixel_mm = grid.voxel_mm;
    geometry.angles_rad = tomo::EvenAngles(views, 180.0);
    geometry.cor_offset_mm = -0.5 * geometry.pixel_mm;
    tomo::Absorbance data;
    data.b.resize(geometry.rays());
    std::ifstream(out + "/tomo_slice_sinogram_noisy.f32", std::ios::binary)
        .read(reinterpret_cast<char*>(data.b.data()), sizeof(float) * data.b.size());
    double noise_sigma = 0.0;
    std::ifstream meta(out + "/tomo_slice.txt");
    for (std::string key; meta >> key;)
      if (key == "noise_sigma") meta >> noise_sigma;
    std::unique_ptr<tomo::Projector> projector;
    tomo::MakeProjector(grid, geometry, ProjectorChoice(), &projector);
    tomo::ReconstructOptions options = Options(*variant);
    options.noise_sigma = noise_sigma;
    Eigen::VectorXf x;
    const tomo::ReconstructionSummary s = tomo::Reconstruct(*projector, data, options, &x);
    tomo::WriteNrrd(out + "/tomo_slice_" + argv[5] + ".nrrd", grid, x);
    std::fprintf(stderr, "%s: %d iterations, %s\n", argv[5], s.iterations, tomo::StopReasonName(s.stop_reason));
    return s.IsSolutionUsable() ? 0 : 1;
  }
  const Slice slice(n, views);
  const bool problem_only = mode == "--problem-only";
  {
    Eigen::VectorXf w_truth;
    slice.projector->Forward(slice.truth, &w_truth);
    std::fprintf(stderr, "model error |W truth - b| = %.4f; noise norm %.4f\n", (w_truth - slice.clean.b).norm(),
                 slice.noise_sigma * std::sqrt(static_cast<double>(slice.clean.b.size())));
  }

  WriteProblem(out, slice, n, views);
  if (problem_only) return 0;
  std::ofstream iterations(out + "/tomo_iterations.csv");
  iterations << "method,noise,iteration,elapsed_ms,error,residual,stopped\n";
  for (const Variant& variant : kVariants)
    for (int noisy = 0; noisy < 2; ++noisy) {
      const tomo::Absorbance& data = noisy ? slice.noisy : slice.clean;
      // The stopped solve, timed on its own, then the full curve (errors
      // computed outside the timed part: the callback's time is subtracted).
      tomo::ReconstructOptions stopped = Options(variant);
      stopped.noise_sigma = noisy ? slice.noise_sigma : 0.002 * slice.noise_sigma;
      Eigen::VectorXf x;
      const tomo::ReconstructionSummary s = tomo::Reconstruct(*slice.projector, data, stopped, &x);
      if (noisy) WritePng(out + "/tomo_slice_" + variant.name + ".png", slice.grid, x, 0.1);

      tomo::ReconstructOptions full = Options(variant);
      full.stop_rule = tomo::StopRule::kIterations;
      full.stagnation_tolerance = 0.0;
      std::vector<double> errors, elapsed;
      double callback_ms = 0.0;
      const double start = CpuMs();
      full.on_iteration = [&](int, const Eigen::VectorXf& v) {
        const double t0 = CpuMs();
        elapsed.push_back(t0 - start - callback_ms);
        errors.push_back(slice.Error(v));
        callback_ms += CpuMs() - t0;
      };
      x.resize(0);
      const tomo::ReconstructionSummary f = tomo::Reconstruct(*slice.projector, data, full, &x);
      for (std::size_t i = 0; i < errors.size(); ++i)
        iterations << variant.name << ',' << noisy << ',' << i + 1 << ',' << elapsed[i] << ','
                   << errors[i] << ',' << f.residual_history[i + 1] << ','
                   << (s.stop_reason == tomo::StopReason::kDiscrepancy && static_cast<int>(i + 1) == s.iterations)
                   << '\n';
      std::fprintf(stderr, "%-7s noise=%d: stopped after %d (%s, %s) error %.4f; best %.4f at %d\n",
                   variant.name, noisy, s.iterations, tomo::StopReasonName(s.stop_reason),
                   photorig::solvers::core::TerminationName(s.termination),
                   errors[static_cast<std::size_t>(std::max(0, s.iterations - 1))],
                   *std::min_element(errors.begin(), errors.end()),
                   static_cast<int>(std::min_element(errors.begin(), errors.end()) - errors.begin()) + 1);
    }

  // Error of the stopped solve against the number of views.
  std::ofstream by_views(out + "/tomo_views.csv");
  by_views << "method,noise,views,iterations,error\n";
  for (int v : {16, 32, 64, 128, 180}) {
    const Slice s(n, v);
    for (const Variant& variant : kVariants)
      for (int noisy = 0; noisy < 2; ++noisy) {
        tomo::ReconstructOptions options = Options(variant);
        options.noise_sigma = noisy ? s.noise_sigma : 0.002 * s.noise_sigma;
        Eigen::VectorXf x;
        const tomo::ReconstructionSummary r = tomo::Reconstruct(*s.projector, noisy ? s.noisy : s.clean, options, &x);
        by_views << variant.name << ',' << noisy << ',' << v << ',' << r.iterations << ','
                 << (r.IsSolutionUsable() ? s.Error(x) : std::nan("")) << '\n';
      }
  }
  return 0;
}
