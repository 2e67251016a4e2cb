// photorig.open_run and photorig.Run (docs/python.md).

#include "arrays.h"
#include "bindings.h"
#include "choices.h"
#include "photorig/daemon/pipelines/color_stack.h"
#include "run.h"

#include <pybind11/stl.h>  // std::optional and std::array options

#include <algorithm>
#include <exception>
#include <limits>
#include <thread>
#include <utility>

namespace photorig::python {

Run::Run(std::string directory) : directory_(std::move(directory)), manifest_(daemon::LoadRunManifest(directory_)) {}

std::vector<const daemon::FrameRecord*> Run::Select(const std::optional<std::string>& kind) const {
  std::optional<config::CaptureStep::Kind> wanted;
  if (kind) {
    wanted = config::CaptureStepKindFromName(*kind);
    if (!wanted) throw py::value_error("kind must be dark, light, flat, pattern or pose, not \"" + *kind + "\"");
  }
  std::vector<const daemon::FrameRecord*> records;
  for (const daemon::FrameRecord& record : manifest_.frames)
    if (!wanted || record.kind == *wanted) records.push_back(&record);
  return records;
}

std::vector<cv::Mat> Run::Load(const std::vector<const daemon::FrameRecord*>& records) const {
  std::vector<cv::Mat> frames(records.size());
  std::vector<std::exception_ptr> errors(records.size());
  const std::size_t workers = std::clamp<std::size_t>(std::thread::hardware_concurrency(), 1, std::max<std::size_t>(1, records.size()));
  std::vector<std::thread> threads;
  for (std::size_t w = 0; w < workers; ++w)
    threads.emplace_back([&, w] {
      for (std::size_t i = w; i < records.size(); i += workers) try {
          frames[i] = daemon::LoadFrame(directory_, *records[i]);
        } catch (...) {
          errors[i] = std::current_exception();
        }
    });
  for (std::thread& thread : threads) thread.join();
  for (const std::exception_ptr& error : errors)
    if (error) std::rethrow_exception(error);
  return frames;
}

std::string RunDirectory(const py::object& run) {
  if (py::isinstance<Run>(run)) return run.cast<const Run&>().directory();
  // A path (str or os.PathLike); None or a number is a mistake, not a folder named "None".
  if (!py::isinstance<py::str>(run) && !py::hasattr(run, "__fspath__"))
    throw py::type_error("run must be a Run, a str or an os.PathLike, not " +
                         py::str(py::type::of(run).attr("__name__")).cast<std::string>());
  return py::str(py::module_::import("os").attr("fspath")(run)).cast<std::string>();
}

namespace {

// The frames' records as columns, row i describing frame i of frames(kind).
py::dict MetadataOf(const std::vector<const daemon::FrameRecord*>& records) {
  // Every column even without a frame (empty, of its type): code that reads
  // one need not ask first whether a run has frames of a kind.
  const auto column = [&](auto field) {
    using Value = decltype(field(std::declval<const daemon::FrameRecord&>()));
    py::array_t<Value> out(static_cast<py::ssize_t>(records.size()));
    for (std::size_t i = 0; i < records.size(); ++i) out.mutable_at(i) = field(*records[i]);
    return out;
  };
  py::dict metadata;
  py::list files, kinds, groups;
  for (const daemon::FrameRecord* record : records) {
    files.append(record->file);
    kinds.append(config::CaptureStepKindName(record->kind));
    groups.append(record->group);
  }
  metadata["file"] = files;
  metadata["kind"] = kinds;
  metadata["group"] = groups;
  metadata["index"] = column([](const daemon::FrameRecord& r) { return r.index; });
  metadata["led"] = column([](const daemon::FrameRecord& r) { return r.led; });
  metadata["level"] = column([](const daemon::FrameRecord& r) { return r.level; });
  metadata["exposure_us"] = column([](const daemon::FrameRecord& r) { return r.exposure_us; });
  metadata["gain_db"] = column([](const daemon::FrameRecord& r) { return r.gain_db; });
  metadata["repeat"] = column([](const daemon::FrameRecord& r) { return r.repeat; });
  metadata["frame_id"] = column([](const daemon::FrameRecord& r) { return r.frame_id; });
  metadata["device_timestamp_ns"] = column([](const daemon::FrameRecord& r) { return r.device_timestamp_ns; });
  metadata["host_timestamp_ns"] = column([](const daemon::FrameRecord& r) { return r.host_timestamp_ns; });
  return metadata;
}

py::dict LightsOf(const daemon::RunManifest& manifest) {
  const std::size_t n = manifest.lights.size();
  std::vector<Eigen::Vector3d> directions, rgb, positions;
  py::array_t<double> intensity(static_cast<py::ssize_t>(n));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t i = 0; i < n; ++i) {
    const config::LedConfig& led = manifest.lights[i];
    directions.push_back(led.direction);
    rgb.push_back(led.rgb_intensity);
    positions.push_back(led.position_mm.value_or(Eigen::Vector3d(nan, nan, nan)));
    intensity.mutable_at(i) = led.intensity;
  }
  py::dict lights;
  lights["direction"] = VectorsToArray(directions);
  lights["intensity"] = intensity;
  lights["rgb_intensity"] = VectorsToArray(rgb);
  lights["position_mm"] = VectorsToArray(positions);  // NaN rows: distant LEDs
  return lights;
}

py::dict CameraOf(const daemon::RunManifest& manifest) {
  py::dict camera;
  camera["projection"] = solvers::camera::ProjectionName(manifest.projection);
  camera["width_px"] = manifest.width;
  camera["height_px"] = manifest.height;
  camera["bit_depth"] = manifest.bit_depth;
  camera["mosaic"] = manifest.mosaic;
  camera["pixel_pitch_mm"] = manifest.pixel_pitch_mm;
  if (manifest.projection == solvers::camera::Projection::kPinhole) {
    const solvers::camera::PinholeLens& lens = manifest.pinhole;
    py::array_t<double> k({3, 3});
    auto view = k.mutable_unchecked<2>();
    const double rows[3][3] = {{lens.fx_px, 0, lens.cx_px}, {0, lens.fy_px, lens.cy_px}, {0, 0, 1}};
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) view(r, c) = rows[r][c];
    camera["camera_matrix"] = k;
    camera["distortion"] = py::array_t<double>(5, lens.distortion.data());
    camera["distance_mm"] = lens.distance_mm;
  }
  return camera;
}

// frames(kind, demosaic, dark_subtracted): see docs/python.md.
py::array Frames(const Run& run, const std::optional<std::string>& kind, const std::optional<std::string>& demosaic,
                 bool dark_subtracted) {
  const daemon::RunManifest& manifest = run.manifest();
  std::optional<solvers::color::DemosaicMethod> method;
  if (demosaic) {
    method = ParseChoice(solvers::color::kDemosaicMethodNames, *demosaic, "demosaic");
    if (!daemon::IsBayerPattern(manifest.mosaic))
      throw py::value_error("demosaic applies to Bayer runs; this run's mosaic is " + manifest.mosaic);
  }
  const std::vector<const daemon::FrameRecord*> records = run.Select(kind);
  std::vector<const daemon::FrameRecord*> darks;
  if (dark_subtracted) {
    darks = run.Select("dark");
    if (darks.empty()) throw py::value_error(run.directory() + " has no dark frames to subtract");
  }
  std::vector<cv::Mat> frames, dark_frames;
  {
    py::gil_scoped_release unlocked;
    frames = run.Load(records);
    dark_frames = run.Load(darks);
    const auto prepare = [&](std::vector<cv::Mat>* list) {
      for (cv::Mat& frame : *list) {
        if (method) frame = daemon::DemosaicToRgb(frame, manifest.mosaic, *method);
        if (dark_subtracted) frame.convertTo(frame, CV_32F);
      }
    };
    prepare(&frames);
    prepare(&dark_frames);
    if (dark_subtracted) {
      cv::Mat mean_dark = cv::Mat::zeros(dark_frames.front().size(), dark_frames.front().type());
      for (const cv::Mat& dark : dark_frames) mean_dark += dark;
      mean_dark /= static_cast<double>(dark_frames.size());
      for (cv::Mat& frame : frames) frame -= mean_dark;
    }
  }
  return StackToArray(frames);
}

}  // namespace

void BindRun(py::module_& m) {
  py::class_<Run>(m, "Run", "A stored run: manifest, frames, lights and camera (docs/python.md).")
      .def_property_readonly("directory", &Run::directory)
      .def_property_readonly(
          "manifest", [](const Run& run) { return ToPython(daemon::ToJson(run.manifest())); },
          "manifest.json as a dict")
      .def(
          "metadata", [](const Run& run, const std::optional<std::string>& kind) { return MetadataOf(run.Select(kind)); },
          py::arg("kind") = py::none(),
          "The frames' records as columns (file, kind, led, exposure_us, ...), row i for frame i of frames(kind)")
      .def_property_readonly("lights", [](const Run& run) { return LightsOf(run.manifest()); },
                             "direction (n, 3), intensity (n,), rgb_intensity (n, 3), position_mm (n, 3; NaN: distant)")
      .def_property_readonly("camera", [](const Run& run) { return CameraOf(run.manifest()); },
                             "projection, size, pixel pitch; camera_matrix and distortion for a pinhole")
      .def(
          "frame",
          [](const Run& run, int index) {
            const auto& frames = run.manifest().frames;
            if (index < 0 || index >= static_cast<int>(frames.size()))
              throw py::index_error("frame " + std::to_string(index) + " of " + std::to_string(frames.size()));
            cv::Mat frame;
            {
              py::gil_scoped_release unlocked;
              frame = daemon::LoadFrame(run.directory(), frames[index]);
            }
            return ToArray(frame);
          },
          py::arg("index"), "Frame `index` of the manifest in raw DN (uint16), without a copy")
      .def("frames", &Frames, py::arg("kind") = py::none(), py::arg("demosaic") = py::none(),
           py::arg("dark_subtracted") = false,
           "Frames of `kind` (dark, light, flat, pattern, pose; None: all) as one (n, rows, cols[, 3]) array: "
           "raw DN (uint16), demosaiced to R, G, B (Bayer runs: bilinear | edge-aware), and/or minus the mean "
           "dark frame (float32)");
  m.def(
      "open_run", [](const std::string& directory) { return Run(directory); }, py::arg("directory"),
      "Opens a run directory (reads its manifest; frames are read when asked for).");
}

}  // namespace photorig::python
