#pragma once
// One directory per run:
//   manifest.json        rig, camera, lights and every frame (written at the end)
//   journal.jsonl        {"run": header}, then one line per frame, appended and
//                        fsynced as it lands, then {"stop": record} at the end
//   frames/NNNN_*.png    16-bit frames, each written durably before the next step
//   ground_truth/        simulated rigs only: normals.tiff, albedo.tiff, mask.png
//   results/<solver>/    solver outputs and report.json

#include "photorig/daemon/io/png16.h"
#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/drivers/camera.h"
#include "photorig/solvers/camera/camera.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <iosfwd>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace photorig::daemon {

// The colour filter of a stored frame: "mono", a Bayer pattern naming the
// top-left 2 x 2 filter block ("RGGB", "BGGR", "GRBG", "GBRG"), or "RGB"
// (three samples per pixel, R, G, B).
bool IsBayerPattern(const std::string& mosaic);
bool IsKnownMosaic(const std::string& mosaic);
int MosaicChannels(const std::string& mosaic);  // samples per stored pixel: 3 for RGB, else 1


struct FrameRecord {
  int index = 0;
  std::string file;        // relative to the run directory
  config::CaptureStep::Kind kind = config::CaptureStep::Kind::kDark;  // stored by CaptureStepKindName
  std::string group;       // the recipe group: "dark", "each_led", "flat", "pattern:<name>", "poses", "reference_target"
  // That group's kind (config::GroupKindOfLabel); nullopt in runs stored before groups existed.
  std::optional<config::Recipe::Group::Kind> group_kind;
  int repeat = 0;          // 0-based repetition of its group
  int led = -1;            // kind "light": index into `lights`; -1 otherwise
  double level = 0.0;      // drive level of that LED
  double exposure_us = 0.0;
  double gain_db = 0.0;
  int bit_depth = 0;
  std::string pixel_format;  // as the camera delivered it (GenICam name); "" in runs stored before it was recorded
  std::uint64_t frame_id = 0;
  std::int64_t device_timestamp_ns = 0;
  std::int64_t host_timestamp_ns = 0;
  std::uint32_t crc32 = 0;  // of the pixel data as stored in the file
  std::optional<config::GonioPose> pose;  // gonioreflectometer arms when the frame was taken
  int pass = 0;  // an adaptive pose plan's added pass (CaptureStep::pass); 0 otherwise, and not stored then
};

// Where a capture stands: kRunning until it ends, then how it ended
// (kInterrupted: finished after a crash without resuming).
enum class CaptureStatus { kRunning, kComplete, kFailed, kAborted, kInterrupted };

// "running", "complete", "failed", "aborted", "interrupted": the words
// manifest.json, journal.jsonl and the HTTP API store.
const char* CaptureStatusName(CaptureStatus status);
std::optional<CaptureStatus> CaptureStatusFromName(const std::string& name);
std::ostream& operator<<(std::ostream& out, CaptureStatus status);  // the name; for logs and test messages

// How a run ended: written to the manifest and as the journal's last line.
struct StopRecord {
  CaptureStatus status = CaptureStatus::kFailed;
  std::string reason;
  int frames = 0;      // frames in the run
  int steps_total = 0;
  int retries = 0;
  int dropped_frames = 0;
};

struct RunManifest {
  std::string format = "photorig-run/1";
  std::string run_id;
  std::string recipe_path;
  std::string recipe_name;
  // The recipe's solve stages, in its words ("photometric_stereo",
  // "light_calibration", ...): what the capture was made for. Empty in runs
  // stored before it was recorded.
  std::vector<std::string> solve_stages;
  std::string rig_path;
  std::string rig_name;
  CaptureStatus status = CaptureStatus::kRunning;
  std::string status_reason;
  std::string sample_name;
  std::string camera_id;
  int width = 0;
  int height = 0;
  int bit_depth = 0;
  // The code at or above which a pixel is clipped (the rig's health
  // saturation_dn: a full well that fills before the ADC's top code); 0 = the
  // top code 2^bit_depth - 1.
  double saturation_dn = 0.0;
  double dn_per_radiance_per_us = 1.0;
  double e_per_dn = 0.0;  // 0 = unknown
  double pixel_pitch_mm = 0.0;  // object-space pixel size (pinhole: on the sample plane); 0 = unknown
  // The camera's projection and, for a pinhole camera, its lens (runs stored
  // before it was recorded read as orthographic).
  solvers::camera::Projection projection = solvers::camera::Projection::kOrthographic;
  solvers::camera::PinholeLens pinhole;
  // The colour filter in front of the sensor, as frames are stored: "mono",
  // a Bayer pattern ("RGGB", "BGGR", "GRBG", "GBRG": the top-left 2 x 2 block;
  // frames are the raw one-channel mosaic) or "RGB" (frames hold R, G, B per
  // pixel). Runs stored before it was recorded read as "mono".
  std::string mosaic = "mono";
  std::string pixel_format;  // the camera's GenICam pixel format, e.g. "BayerRG12"; "" when not recorded
  // The rig's camera.color_model when the run was captured: its path and
  // content hash (config::ContentHash); empty without one.
  std::string color_model_path;
  std::string color_model_hash;
  std::vector<config::LedConfig> lights;
  // A gonioreflectometer's reference target (rig `reference_target:`), whose
  // frames are those of group "reference_target": its diffuse albedo, unset
  // when the rig names none.
  std::optional<double> reference_albedo;
  std::vector<FrameRecord> frames;
  bool has_ground_truth = false;
  std::optional<StopRecord> stop;
};

// What reopening an interrupted run found and repaired.
struct RecoveryReport {
  int frames_kept = 0;
  int frames_discarded = 0;        // journalled but missing or failing their checksum
  bool journal_tail_torn = false;  // a partly written last line was cut off
  std::vector<std::string> removed_files;  // temp files and frames the journal does not vouch for
};

nlohmann::json ToJson(const FrameRecord& frame);
FrameRecord FrameRecordFromJson(const nlohmann::json& json);
nlohmann::json ToJson(const StopRecord& stop);
StopRecord StopRecordFromJson(const nlohmann::json& json);
nlohmann::json ToJson(const RunManifest& manifest);
RunManifest RunManifestFromJson(const nlohmann::json& json);

class RunWriter {
 public:
  // Creates `directory` (which must not exist or be empty). Throws on I/O error.
  RunWriter(std::string directory, RunManifest header);
  // Reopens an interrupted run from its journal: cuts a torn last line, drops
  // records whose frame is missing or corrupt, removes temp files and frames
  // the journal does not vouch for. The frames kept are the run's checkpoint.
  // Throws std::runtime_error naming the file when the journal header is unreadable.
  static std::unique_ptr<RunWriter> Reopen(const std::string& directory, RecoveryReport* report);
  ~RunWriter();
  RunWriter(const RunWriter&) = delete;
  RunWriter& operator=(const RunWriter&) = delete;

  const std::string& directory() const { return directory_; }
  const RunManifest& manifest() const { return manifest_; }

  // Durably stores the frame and appends it to the journal before returning.
  const FrameRecord& WriteFrame(const config::CaptureStep& step, const drivers::Frame& frame);
  // normals, albedo, mask, height (mm), specular BRDF parameters and, for
  // volumes, line integrals, as ground_truth/*.tiff|png; the lights as they
  // really are (which may differ from the rig's nominal ones) as
  // ground_truth/light_directions.txt, one "x y z" line per light, and for
  // near LEDs their positions (mm) as ground_truth/light_positions.txt.
  // A colour camera's scene also has its albedo in linear sRGB (albedo_rgb,
  // CV_32FC3 R, G, B) as ground_truth/albedo_rgb.tiff. A scene whose paints
  // have their own lobes has its material map (the paint per pixel, 255 off
  // the object) as ground_truth/material.png.
  void WriteGroundTruth(const sim::SurfaceMaps& surface, const std::vector<sim::Light>& lights,
                        const cv::Mat& albedo_rgb = cv::Mat());
  // A volume (a tomography phantom or density grid) has no surface and is
  // not lit by LEDs: its truth is the phantom (`phantom_json`, as
  // ground_truth/phantom.json) or the line integrals through the grid
  // (line_integrals.tiff), whichever is given.
  void WriteVolumeGroundTruth(const cv::Mat& line_integrals, const std::string& phantom_json);
  bool HasFrame(int step_index) const;
  // Appends the stop record to the journal and writes manifest.json.
  void Finish(const StopRecord& stop);

 private:
  RunWriter() = default;
  void AppendJournal(const nlohmann::json& line);  // and fdatasync it
  void AppendJournalUnsynced(const nlohmann::json& line);

  std::string directory_;
  RunManifest manifest_;
  int journal_fd_ = -1;
  Png16Encoder encoder_;
};

// A stored run that cannot be read: its manifest or a frame is missing,
// truncated, corrupt or fails its checksum. The input is damaged, not the
// solve: the command exits 2, as for any other unreadable input, and the
// message names the file and what to do.
class DamagedRunError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Reads manifest.json. Throws std::invalid_argument naming the directory when
// it holds no manifest (not a run: the caller named the wrong folder), and
// DamagedRunError naming the file on a corrupt one.
RunManifest LoadRunManifest(const std::string& directory);

// What a run's capture says about solving it, from its manifest: a capture
// that did not complete (failed health checks, a device fault, aborted,
// interrupted) is not solved unless the caller accepts it, and then every
// report solved from it carries this verdict.
struct CaptureVerdict {
  CaptureStatus status = CaptureStatus::kComplete;
  std::vector<std::string> reasons;  // the stop record's findings, one each
  bool accepted_failed_capture = false;

  bool complete() const { return status == CaptureStatus::kComplete; }
  // {"status", "reasons", "accepted_failed_capture"}: report.json's "capture".
  nlohmann::json ToJson() const;
};
CaptureVerdict CaptureVerdictOf(const RunManifest& manifest);

// Whether a solve goes ahead on a capture that did not complete.
enum class FailedCapture { kRefuse, kAccept };

// A solve refused because its run's capture did not complete: a failed
// result, not a usage error (exit code 1).
class FailedCaptureError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The run's verdict for a solve. Throws FailedCaptureError, naming the run,
// its verdict and reasons and what to do, when the capture did not complete
// and `failed` is kRefuse; with kAccept the verdict says it was accepted.
CaptureVerdict CheckCaptureForSolve(const std::string& directory, const RunManifest& manifest, FailedCapture failed);
// Loads a frame as 16-bit (one channel, or three in R, G, B order for an RGB
// run) and checks the checksum against its record; DamagedRunError, naming
// the file, where it cannot.
cv::Mat LoadFrame(const std::string& directory, const FrameRecord& record);
// Checks a finished run: every step's frame present exactly once, intact, and
// nothing else in frames/. Returns the problems found (empty when sound).
std::vector<std::string> VerifyRun(const std::string& directory);

}  // namespace photorig::daemon
