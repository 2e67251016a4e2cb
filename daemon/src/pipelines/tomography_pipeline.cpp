
#include "photorig/daemon/pipelines/tomography_pipeline.h"
#include "photorig/daemon/pipelines/internal/phantom_json.h"

#if PHOTORIG_HAVE_OPENVDB
#include "photorig/daemon/io/internal/vdb_volume.h"
#endif

#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/json_fields.h"
#include "photorig/daemon/pipelines/internal/results_folder.h"
#include "photorig/solvers/core/summary_json.h"
#include "photorig/daemon/capture/run_store.h"
#include "photorig/solvers/tomography/nrrd.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace photorig::daemon {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

double MillisecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

std::vector<std::uint16_t> Pixels(const cv::Mat& frame, const std::string& what) {
  if (frame.type() != CV_16UC1) throw std::invalid_argument(what + ": not a 16-bit grey frame");
  cv::Mat dense = frame.isContinuous() ? frame : frame.clone();
  const auto* data = dense.ptr<std::uint16_t>();
  return {data, data + dense.total()};
}

// Refuses input the solver would misread: frame sizes against the detector,
// one angle per projection, at least one flat and one dark.
void CheckInput(const TomographyInput& input) {
  const solvers::tomography::Geometry& g = input.geometry;
  if (std::string why; !g.IsValid(&why)) throw std::invalid_argument(input.source + ": geometry: " + why);
  if (input.projections.empty()) throw std::invalid_argument(input.source + ": no projections");
  if (static_cast<int>(input.projections.size()) != g.views())
    throw std::invalid_argument(input.source + ": " + std::to_string(input.projections.size()) + " projections but " +
                                std::to_string(g.views()) + " angles in the geometry");
  if (input.flats.empty())
    throw std::invalid_argument(input.source + ": no flat fields (frames of the open beam, the sample out of it); "
                                "b = -log(L / L_flat) needs at least one, and two or more give the noise the "
                                "discrepancy rule stops at");
  if (input.darks.empty())
    throw std::invalid_argument(input.source + ": no dark frames (backlight off); the black level would stay in b");
  const std::size_t pixels = static_cast<std::size_t>(g.pixels_per_view());
  auto check = [&](const std::vector<std::vector<std::uint16_t>>& frames, const char* what) {
    for (const auto& f : frames)
      if (f.size() != pixels)
        throw std::invalid_argument(input.source + ": a " + std::string(what) + " frame has " + std::to_string(f.size()) +
                                    " pixels; the detector in the geometry has " + std::to_string(g.detector_cols) +
                                    " x " + std::to_string(g.detector_rows));
  };
  check(input.projections, "projection");
  check(input.flats, "flat");
  check(input.darks, "dark");
}

json GeometryToJson(const solvers::tomography::Geometry& g, double saturation_dn) {
  json angles = json::array();
  for (double a : g.angles_rad) angles.push_back(a / kDeg);
  json out = {{"beam", g.beam == solvers::tomography::Beam::kParallel ? "parallel" : "cone"},
              {"detector_cols", g.detector_cols},
              {"detector_rows", g.detector_rows},
              {"pixel_mm", g.pixel_mm},
              {"cor_offset_mm", g.cor_offset_mm},
              {"angles_deg", angles},
              {"saturation_dn", saturation_dn}};
  if (g.beam == solvers::tomography::Beam::kCone) {
    out["source_to_axis_mm"] = g.source_to_axis_mm;
    out["axis_to_detector_mm"] = g.axis_to_detector_mm;
  }
  return out;
}

solvers::tomography::Geometry GeometryFromJson(const json& j, const std::string& path, double* saturation_dn) {
  solvers::tomography::Geometry g;
  try {
    const std::string beam = j.value("beam", "parallel");
    if (beam != "parallel" && beam != "cone") throw std::invalid_argument("beam '" + beam + "' (expected parallel or cone)");
    g.beam = beam == "cone" ? solvers::tomography::Beam::kCone : solvers::tomography::Beam::kParallel;
    g.detector_cols = IntegerAt<int>(j, "detector_cols");
    g.detector_rows = IntegerAt<int>(j, "detector_rows");
    g.pixel_mm = j.at("pixel_mm").get<double>();
    g.cor_offset_mm = j.value("cor_offset_mm", 0.0);
    g.source_to_axis_mm = j.value("source_to_axis_mm", g.source_to_axis_mm);
    g.axis_to_detector_mm = j.value("axis_to_detector_mm", g.axis_to_detector_mm);
    if (j.contains("angles_deg"))
      for (double deg : j.at("angles_deg").get<std::vector<double>>()) g.angles_rad.push_back(deg * kDeg);
    *saturation_dn = j.value("saturation_dn", 4095.0);
  } catch (const json::exception& e) {
    throw std::invalid_argument(path + ": " + e.what());
  } catch (const std::runtime_error& e) {  // an integer field that is no integer (json_fields.h)
    throw std::invalid_argument(path + ": " + e.what());
  }
  return g;
}

std::vector<std::vector<std::uint16_t>> ReadFrames(const fs::path& folder) {
  std::vector<fs::path> files;
  if (fs::is_directory(folder))
    for (const auto& entry : fs::directory_iterator(folder))
      if (const fs::path ext = entry.path().extension(); ext == ".png" || ext == ".tif" || ext == ".tiff")
        files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  std::vector<std::vector<std::uint16_t>> frames;
  for (const fs::path& file : files)
    frames.push_back(Pixels(ReadInputImage(file.string()), file.string()));
  return frames;
}

// angles.txt: the view angles in degrees, whitespace-separated, '#' to the end of a line a comment.
std::vector<double> ReadAnglesFile(const fs::path& path) {
  std::ifstream in(path);
  std::vector<double> angles_rad;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line.substr(0, line.find('#')));
    std::string word;
    while (words >> word) {
      std::size_t used = 0;
      double deg = 0.0;
      try {
        deg = std::stod(word, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != word.size() || !std::isfinite(deg))
        throw std::invalid_argument(path.string() + ": '" + word + "' is not an angle in degrees");
      angles_rad.push_back(deg * kDeg);
    }
  }
  return angles_rad;
}

std::shared_ptr<const sim::Phantom> ReadPhantom(const fs::path& path) {
  if (!fs::exists(path)) return nullptr;
  std::ifstream in(path);
  try {
    return std::make_shared<const sim::Phantom>(PhantomFromJson(json::parse(in)));
  } catch (const std::exception& e) {
    throw std::invalid_argument(path.string() + ": " + e.what());
  }
}

// 8-bit slice with +y (or +z) upwards, 0 .. top_per_mm mapped to 0 .. 255.
cv::Mat SliceImage(const solvers::tomography::VolumeGrid& grid, const Eigen::VectorXf& v, bool axial, double top_per_mm) {
  const int width = grid.nx, height = axial ? grid.ny : grid.nz;
  cv::Mat image(height, width, CV_8U);
  for (int row = 0; row < height; ++row)
    for (int i = 0; i < width; ++i) {
      const int up = height - 1 - row;
      const std::int64_t index = axial ? grid.Index(i, up, grid.nz / 2) : grid.Index(i, grid.ny / 2, up);
      const double value = top_per_mm > 0 ? v[index] / top_per_mm : 0.0;
      image.at<std::uint8_t>(row, i) = cv::saturate_cast<std::uint8_t>(255.0 * std::clamp(value, 0.0, 1.0));
    }
  return image;
}

}  // namespace

json PhantomToJson(const sim::Phantom& phantom) {
  json ellipsoids = json::array();
  for (const sim::Ellipsoid& e : phantom.ellipsoids)
    ellipsoids.push_back({e.amplitude, e.a, e.b, std::isinf(e.c) ? json("inf") : json(e.c), e.x0, e.y0, e.z0,
                          e.phi_deg, e.theta_deg, e.psi_deg});
  return {{"half_extent_mm", phantom.half_extent_mm},
          {"sigma_per_mm", phantom.sigma_per_mm},
          {"ellipsoids", ellipsoids},
          {"columns", {"amplitude", "a", "b", "c", "x0", "y0", "z0", "phi_deg", "theta_deg", "psi_deg"}}};
}

sim::Phantom PhantomFromJson(const json& j) {
  sim::Phantom phantom;
  phantom.half_extent_mm = j.at("half_extent_mm").get<double>();
  phantom.sigma_per_mm = j.at("sigma_per_mm").get<double>();
  for (const json& row : j.at("ellipsoids")) {
    if (row.size() != 10) throw std::invalid_argument("an ellipsoid has 10 numbers");
    auto at = [&row](int k) {
      return row[k].is_string() && row[k] == "inf" ? std::numeric_limits<double>::infinity() : row[k].get<double>();
    };
    phantom.ellipsoids.push_back({at(0), at(1), at(2), at(3), at(4), at(5), at(6), at(7), at(8), at(9)});
  }
  return phantom;
}

TomographyInput LoadTomographyRun(const std::string& run_directory, FailedCapture failed) {
  const RunManifest manifest = LoadRunManifest(run_directory);
  TomographyInput input;
  input.source = run_directory;
  input.capture = CheckCaptureForSolve(run_directory, manifest, failed);
  input.loading = {{"accept_failed_capture", failed == FailedCapture::kAccept}};
  std::vector<double> angles_deg;
  for (const FrameRecord& record : manifest.frames) {
    if (record.kind == config::CaptureStep::Kind::kDark) {
      input.darks.push_back(Pixels(LoadFrame(run_directory, record), record.file));
    } else if (record.kind == config::CaptureStep::Kind::kPose && record.pose) {
      const bool open_beam = record.pose->sample_changer_deg && *record.pose->sample_changer_deg != 0.0;
      (open_beam ? input.flats : input.projections).push_back(Pixels(LoadFrame(run_directory, record), record.file));
      if (!open_beam) angles_deg.push_back(record.pose->sample_rotation_deg);
    }
  }
  if (manifest.pixel_pitch_mm <= 0.0)
    throw std::invalid_argument(run_directory + ": the run does not record the camera's pixel pitch (the detector's)");
  if (input.projections.empty())
    throw std::invalid_argument(run_directory + ": no projections (pose frames with the sample in the beam); "
                                "is this a tomography run (config/recipes/tomography.yaml)?");
  input.geometry.detector_cols = manifest.width;
  input.geometry.detector_rows = manifest.height;
  input.geometry.pixel_mm = manifest.pixel_pitch_mm;
  for (double deg : angles_deg) input.geometry.angles_rad.push_back(deg * kDeg);
  input.saturation_dn = manifest.saturation_dn > 0.0 ? manifest.saturation_dn : std::ldexp(1.0, manifest.bit_depth) - 1.0;
  input.phantom = ReadPhantom(fs::path(run_directory) / "ground_truth" / "phantom.json");
  CheckInput(input);
  return input;
}

TomographyInput LoadProjectionFolder(const std::string& directory) {
  const fs::path geometry_path = fs::path(directory) / "geometry.json";
  if (!fs::exists(geometry_path))
    throw std::invalid_argument(directory + ": no geometry.json (beam, detector, pixel_mm, angles_deg)");
  TomographyInput input;
  input.source = directory;
  std::ifstream in(geometry_path);
  json j;
  try {
    j = json::parse(in);
  } catch (const json::exception& e) {
    throw std::invalid_argument(geometry_path.string() + ": " + e.what());
  }
  input.geometry = GeometryFromJson(j, geometry_path.string(), &input.saturation_dn);
  const fs::path angles_path = fs::path(directory) / "angles.txt";
  if (fs::exists(angles_path)) {
    if (!input.geometry.angles_rad.empty())
      throw std::invalid_argument(directory + ": angles both in geometry.json (angles_deg) and in angles.txt; keep one");
    input.geometry.angles_rad = ReadAnglesFile(angles_path);
  }
  if (input.geometry.angles_rad.empty())
    throw std::invalid_argument(directory + ": no view angles (angles_deg in geometry.json, or angles.txt)");
  input.projections = ReadFrames(fs::path(directory) / "projections");
  input.flats = ReadFrames(fs::path(directory) / "flats");
  input.darks = ReadFrames(fs::path(directory) / "darks");
  input.phantom = ReadPhantom(fs::path(directory) / "phantom.json");
  CheckInput(input);
  return input;
}

TomographyInput LoadTomographyInput(const std::string& path, FailedCapture failed) {
  return fs::exists(fs::path(path) / "manifest.json") ? LoadTomographyRun(path, failed) : LoadProjectionFolder(path);
}

void WriteProjectionFolder(const TomographyInput& input, const std::string& directory) {
  const solvers::tomography::Geometry& g = input.geometry;
  auto write = [&](const std::vector<std::vector<std::uint16_t>>& frames, const char* folder) {
    fs::create_directories(fs::path(directory) / folder);
    for (std::size_t i = 0; i < frames.size(); ++i) {
      char name[32];
      std::snprintf(name, sizeof(name), "%04zu.png", i);
      const cv::Mat frame(g.detector_rows, g.detector_cols, CV_16U, const_cast<std::uint16_t*>(frames[i].data()));
      WriteImage((fs::path(directory) / folder / name).string(), frame);
    }
  };
  write(input.projections, "projections");
  write(input.flats, "flats");
  write(input.darks, "darks");
  WriteFileDurably((fs::path(directory) / "geometry.json").string(), GeometryToJson(g, input.saturation_dn).dump(2) + "\n");
  if (input.phantom)
    WriteFileDurably((fs::path(directory) / "phantom.json").string(), PhantomToJson(*input.phantom).dump(2) + "\n");
}

SystemMatrixFactory InProcessSystemMatrix() {
  return [](const solvers::tomography::VolumeGrid& grid, const solvers::tomography::Geometry& geometry,
            const solvers::tomography::ProjectorOptions& options, std::unique_ptr<solvers::tomography::SystemMatrix>* matrix,
            std::int64_t* first_ray) {
    std::unique_ptr<solvers::tomography::Projector> projector;
    solvers::tomography::ProjectorSummary summary = solvers::tomography::MakeProjector(grid, geometry, options, &projector);
    *matrix = std::move(projector);
    *first_ray = 0;
    return summary;
  };
}

TomographyResult SolveTomography(const TomographyInput& input, const config::TomographyRequest& request,
                                 const SystemMatrixFactory& factory) {
  const auto started = std::chrono::steady_clock::now();
  if (std::string why; !request.IsValid(&why)) throw std::invalid_argument(why);
  TomographyResult result;
  result.capture = input.capture;
  result.provenance = MakeProvenance("tomography", input.source, RequestJson(request), input.loading);
  result.geometry = input.geometry;
  if (request.cor_offset_mm) result.geometry.cor_offset_mm += *request.cor_offset_mm;
  const solvers::tomography::Geometry& g = result.geometry;
  result.grid.nx = request.volume[0] > 0 ? request.volume[0] : g.detector_cols;
  result.grid.ny = request.volume[1] > 0 ? request.volume[1] : g.detector_cols;
  result.grid.nz = request.volume[2] > 0 ? request.volume[2] : g.detector_rows;
  result.grid.voxel_mm = request.voxel_mm > 0.0 ? request.voxel_mm : g.pixel_mm;
  if (std::string why; !result.grid.IsValid(&why)) throw std::invalid_argument("volume: " + why);

  solvers::tomography::AbsorbanceOptions absorbance_options;
  absorbance_options.saturation_dn = input.saturation_dn;
  solvers::tomography::Absorbance all;
  result.absorbance = solvers::tomography::ComputeAbsorbance(g, input.projections, input.flats, input.darks, absorbance_options, &all);
  result.absorbance_ms = MillisecondsSince(started);
  auto fail = [&](solvers::core::Termination how, const std::string& why) {
    result.reconstruction.End(how, why);
    result.total_ms = MillisecondsSince(started);
    return result;
  };
  if (!result.absorbance.IsSolutionUsable()) return fail(result.absorbance.termination, "absorbance: " + result.absorbance.message);
  if (request.ring_filter) {
    result.ring_filter = solvers::tomography::RemoveStripes(g, {}, &all);
    if (!result.ring_filter->IsSolutionUsable()) return fail(result.ring_filter->termination, "ring filter: " + result.ring_filter->message);
  }
  if (!request.cor_offset_mm) {
    result.cor = solvers::tomography::FindCorOffset(g, all);
    if (!result.cor->IsSolutionUsable())
      return fail(solvers::core::Termination::kFailure,
                  "centre of rotation: " + result.cor->message + "; give it (--cor-offset-mm, or cor_offset_mm in the recipe)");
    result.geometry.cor_offset_mm = result.cor->offset_mm;
  }

  solvers::tomography::ReconstructOptions options;
  options.method = request.method;
  options.total_variation = request.total_variation;
  options.max_iterations = request.max_iterations;
  options.iteration_limit_name = request.iteration_limit_name;
  options.discrepancy_factor = request.discrepancy_factor;
  if (request.held_out) {
    solvers::tomography::HeldOutOptions held_out;
    held_out.reconstruct = options;
    held_out.interpolation = request.projector;
    // Without a noise estimate for the discrepancy rule, the held-out
    // residual's minimum says where to stop.
    result.stopped_by_held_out = all.variance.size() == 0;
    if (result.stopped_by_held_out) {
      held_out.reconstruct.stop_rule = solvers::tomography::StopRule::kIterations;
      held_out.track_iterations = true;
    }
    result.held_out = solvers::tomography::HeldOutResidual(result.grid, g, all, held_out);
    if (result.stopped_by_held_out) {
      if (!result.held_out->IsSolutionUsable())
        return fail(solvers::core::Termination::kFailure, "no noise estimate for the discrepancy rule, and the held-out "
                                                          "stopping rule failed: " + result.held_out->message);
      options.stop_rule = solvers::tomography::StopRule::kIterations;
      options.max_iterations = result.held_out->best_iteration;
      result.held_out->relative_residual = result.held_out->residual_history[result.held_out->best_iteration - 1];
    }
  }
  options.progress = request.progress;

  solvers::tomography::ProjectorOptions projector_options;
  projector_options.interpolation = request.projector;
  projector_options.progress = request.progress;
  std::unique_ptr<solvers::tomography::SystemMatrix> matrix;
  std::int64_t first_ray = 0;
  result.projector = factory(result.grid, g, projector_options, &matrix, &first_ray);
  if (!result.projector.IsSolutionUsable()) throw std::invalid_argument("projector: " + result.projector.message);

  // The rays this matrix holds.
  solvers::tomography::Absorbance held;
  const std::int64_t n = matrix->rays();
  held.b = all.b.segment(first_ray, n);
  if (!all.valid.empty()) held.valid.assign(all.valid.begin() + first_ray, all.valid.begin() + first_ray + n);
  if (all.variance.size() > 0) held.variance = all.variance.segment(first_ray, n);
  all = solvers::tomography::Absorbance();  // a process of a distributed solve keeps its rays only

  result.reconstruction = solvers::tomography::Reconstruct(*matrix, held, options, &result.sigma);
  // A process of a slab decomposition holds its slab: the whole volume goes to the one that writes.
  if (result.sigma.size() == matrix->voxels()) matrix->GatherVolume(&result.sigma);

  if (input.phantom && result.reconstruction.IsSolutionUsable() && result.sigma.size() == result.grid.voxels()) {
    const std::vector<float> truth = input.phantom->Rasterise(result.grid, 4);
    const double radius = 0.5 * g.detector_cols * g.pixel_mm;
    double error2 = 0.0, truth2 = 0.0;
    for (int k = 0; k < result.grid.nz; ++k)
      for (int j = 0; j < result.grid.ny; ++j)
        for (int i = 0; i < result.grid.nx; ++i) {
          const Eigen::Vector3d c = result.grid.VoxelCentre(i, j, k);
          if (c.head<2>().norm() > radius) continue;
          const std::int64_t index = result.grid.Index(i, j, k);
          const double t = truth[static_cast<std::size_t>(index)];
          error2 += (result.sigma[index] - t) * (result.sigma[index] - t);
          truth2 += t * t;
        }
    if (truth2 > 0.0) result.relative_error_vs_truth = std::sqrt(error2 / truth2);
  }
  result.total_ms = MillisecondsSince(started);
  return result;
}

json TomographyResult::ToJson() const {
  const solvers::tomography::ReconstructionSummary& r = reconstruction;
  json doc = solvers::core::ToJson(r);
  doc.update(
      {{"method", solvers::tomography::MethodName(r.method)},
       {"trusted", trusted()},
       {"iterations", r.iterations},
       {"stop_reason", stopped_by_held_out ? "held-out-minimum" : solvers::tomography::StopReasonName(r.stop_reason)},
       {"relaxation", r.relaxation},
       {"tv_strength", r.tv_strength},
       {"residual", r.residual_history.empty() ? 0.0 : r.residual_history.back()},
       {"discrepancy_target", r.discrepancy_target},
       {"residual_history", r.residual_history},
       {"rays_used", r.rays_used},
       {"voxels_reached", r.voxels_reached},
       {"voxels_unreached", r.voxels_unreached},
       {"underdetermined", r.underdetermined},
       {"inconsistent", r.inconsistent},
       {"volume", {{"nx", grid.nx}, {"ny", grid.ny}, {"nz", grid.nz}, {"voxel_mm", grid.voxel_mm}}},
       {"projector",
        {{"sparse", projector.sparse}, {"nonzeros", projector.nonzeros}, {"stored_bytes", projector.stored_bytes}}},
       {"geometry", GeometryToJson(geometry, 0.0)}});
  // timings_ms: the reconstruction's setup and solve, the stages before it,
  // and the whole stage as its total.
  doc["timings_ms"].update({{"absorbance", absorbance_ms}, {"projector", projector.total_ms}, {"total", total_ms}});
  doc["absorbance"] = solvers::core::ToJson(absorbance);
  doc["absorbance"].update({{"rays", absorbance.rays},
                            {"flagged_non_positive", absorbance.flagged_non_positive},
                            {"flagged_saturated", absorbance.flagged_saturated},
                            {"flagged_no_flat", absorbance.flagged_no_flat},
                            {"noise_estimated", absorbance.noise_estimated},
                            {"mean_b_sigma", absorbance.mean_b_sigma}});
  doc["geometry"].erase("saturation_dn");
  doc["geometry"]["views"] = geometry.views();
  doc["centre_of_rotation"] = {{"source", cor ? "estimated" : "given"},
                                {"offset_mm", geometry.cor_offset_mm},
                                {"offset_px", geometry.cor_offset_mm / geometry.pixel_mm}};
  if (cor) {
    json& c = doc["centre_of_rotation"];
    c.update(solvers::core::ToJson(*cor));
    c["method"] = solvers::tomography::CorMethodName(cor->method);
    c["sigma_mm"] = cor->offset_sigma_mm;
    c["sigma_px"] = cor->offset_sigma_mm / geometry.pixel_mm;
    c["tilt_deg"] = cor->tilt_deg;
    c["tilt_sigma_deg"] = cor->tilt_sigma_deg;
    c["pairs"] = cor->pairs;
    c["candidates"] = cor->candidates;
  }
  if (held_out) {
    doc["held_out"] = solvers::core::ToJson(*held_out);
    doc["held_out"].update(
        {{"relative_residual", held_out->relative_residual},
         {"noise_floor", held_out->noise_floor},
         {"fit_views", held_out->fit_views},
         {"held_out_views", held_out->held_out_views},
         {"iterations", stopped_by_held_out ? held_out->best_iteration : held_out->reconstruction.iterations},
         {"stopping_rule", stopped_by_held_out}});
  }
  if (ring_filter) {
    doc["ring_filter"] = solvers::core::ToJson(*ring_filter);
    doc["ring_filter"].update({{"stripes", ring_filter->stripes}, {"max_offset", ring_filter->max_offset}});
  }
  if (relative_error_vs_truth) doc["relative_error_vs_truth"] = *relative_error_vs_truth;
  if (capture) doc["capture"] = capture->ToJson();
  doc["provenance"] = provenance.ToJson();
  return doc;
}

namespace {

void WriteTomographyFiles(const TomographyInput& input, const TomographyResult& result, const fs::path& out) {
  WriteFileDurably((out / "report.json").string(), result.ToJson().dump(2) + "\n");
  WriteFileDurably((out / "geometry.json").string(), GeometryToJson(result.geometry, input.saturation_dn).dump(2) + "\n");
  if (result.sigma.size() != result.grid.voxels()) return;  // nothing reconstructed
  if (const solvers::core::Summary written = solvers::tomography::WriteNrrd((out / "volume.nrrd").string(), result.grid, result.sigma);
      !written.IsSolutionUsable())
    throw std::runtime_error(written.message);
#if PHOTORIG_HAVE_OPENVDB
  if (const solvers::core::Summary written = WriteVdb((out / "volume.vdb").string(), result.grid, result.sigma);
      !written.IsSolutionUsable())
    throw std::runtime_error(written.message);
#endif
  // One scale for the reconstruction and the truth: the phantom's peak, else the volume's.
  double top = result.sigma.maxCoeff();
  Eigen::VectorXf truth;
  if (input.phantom) {
    const std::vector<float> raster = input.phantom->Rasterise(result.grid, 2);
    truth = Eigen::Map<const Eigen::VectorXf>(raster.data(), static_cast<Eigen::Index>(raster.size()));
    top = truth.maxCoeff();
  }
  WriteImage((out / "slice_z.png").string(), SliceImage(result.grid, result.sigma, true, top));
  WriteImage((out / "slice_y.png").string(), SliceImage(result.grid, result.sigma, false, top));
  if (truth.size() > 0) {
    WriteImage((out / "truth_z.png").string(), SliceImage(result.grid, truth, true, top));
    WriteImage((out / "truth_y.png").string(), SliceImage(result.grid, truth, false, top));
  }
}

}  // namespace

void WriteTomographyResults(const TomographyInput& input, const TomographyResult& result, const std::string& destination) {
  ResultsFolder folder(destination);
  try {
    WriteTomographyFiles(input, result, folder.path());
  } catch (...) {
    folder.Abandon(std::current_exception());
  }
  folder.Commit();
}

}  // namespace photorig::daemon
