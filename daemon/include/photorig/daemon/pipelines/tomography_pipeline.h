#pragma once
// A turntable scan from its stored frames to a reconstructed volume: the
// frames and their geometry read from a run (config/recipes/tomography.yaml)
// or from a folder of projections, converted to absorbance with the flats and
// darks, reconstructed (solvers/tomography), compared with the phantom when
// the run was simulated, and written as NRRD, report.json and slice previews.
// Shared by `photorig solve tomography`, the recipe's `tomography:` stage and
// the MPI-distributed `photorig-tomo-mpi`.
//
// A folder of projections holds geometry.json {"beam": "parallel" | "cone",
// "detector_cols", "detector_rows", "pixel_mm", "angles_deg": [...],
// "cor_offset_mm", "source_to_axis_mm", "axis_to_detector_mm" (cone),
// "saturation_dn"}, projections/ (16-bit PNG or TIFF, one per angle in name
// order), flats/, darks/ (one or more each), and optionally phantom.json (the
// ground truth). The angles may instead be in angles.txt (degrees, one per
// projection in the same order); any order, repeats and any range are taken.

#include "photorig/daemon/capture/run_store.h"
#include "photorig/daemon/pipelines/provenance.h"
#include "photorig/config/solve_requests.h"
#include "photorig/solvers/tomography/absorbance.h"
#include "photorig/solvers/tomography/center_of_rotation.h"
#include "photorig/solvers/tomography/held_out.h"
#include "photorig/solvers/tomography/projector.h"
#include "photorig/solvers/tomography/reconstruct.h"
#include "photorig/solvers/tomography/ring_filter.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace photorig::sim {
struct Phantom;
}  // namespace photorig::sim

namespace photorig::daemon {

struct TomographyInput {
  std::string source;              // the run or folder it came from
  solvers::tomography::Geometry geometry;   // one angle per projection; cor_offset_mm as stored
  std::vector<std::vector<std::uint16_t>> projections, flats, darks;
  double saturation_dn = 4095.0;
  // Ground truth of a simulated scan (photorig/sim/phantom.h); null for a real one.
  std::shared_ptr<const sim::Phantom> phantom;
  // A run's capture verdict (CheckCaptureForSolve); unset for a projection folder.
  std::optional<CaptureVerdict> capture;
  // How the frames were read, for the result's provenance: "accept_failed_capture".
  nlohmann::json loading = nlohmann::json::object();
};

// Both throw std::invalid_argument naming what is missing or inconsistent
// (no flats or darks, frames of another size, angles that do not match the
// projections, a geometry the solver refuses): bad input, exit code 2.
// A run's projections are its pose frames with the sample in the beam
// (sample_changer_deg 0), flats the poses with it out, darks its dark frames;
// the angles are the turntable's, the detector the camera's size and pitch,
// the beam parallel (the simulated tomograph's telecentric camera).
// A run whose capture did not complete is refused (FailedCaptureError) unless
// `failed` accepts it.
TomographyInput LoadTomographyRun(const std::string& run_directory, FailedCapture failed = FailedCapture::kRefuse);
TomographyInput LoadProjectionFolder(const std::string& directory);
// A run directory (manifest.json) or a folder of projections.
TomographyInput LoadTomographyInput(const std::string& path, FailedCapture failed = FailedCapture::kRefuse);

// Writes a folder of projections (the layout above) from frames in memory.
void WriteProjectionFolder(const TomographyInput& input, const std::string& directory);

// What builds W for the solve: MakeProjector in one process; the MPI module
// gives a factory whose matrix holds this process's block of views.
// `first_ray` is the first of the scan's rays the matrix holds (its rows are
// rays first_ray .. first_ray + rays() - 1).
using SystemMatrixFactory = std::function<solvers::tomography::ProjectorSummary(
    const solvers::tomography::VolumeGrid&, const solvers::tomography::Geometry&, const solvers::tomography::ProjectorOptions&,
    std::unique_ptr<solvers::tomography::SystemMatrix>*, std::int64_t* first_ray)>;
SystemMatrixFactory InProcessSystemMatrix();

struct TomographyResult {
  solvers::tomography::Geometry geometry;  // with the centre of rotation solved with
  solvers::tomography::VolumeGrid grid;
  solvers::tomography::AbsorbanceSummary absorbance;
  std::optional<solvers::tomography::RingFilterSummary> ring_filter;  // when asked for
  // The centre estimated from the data (FindCorOffset), unless the request gave one.
  std::optional<solvers::tomography::CorEstimateSummary> cor;
  // The held-out-angle residual of the same solve on half the views (held_out.h),
  // unless the request turned it off.
  std::optional<solvers::tomography::HeldOutSummary> held_out;
  // The scan had no noise estimate (fewer than two flats or darks): the solve
  // ran the iterations at which the held-out residual was lowest instead of
  // the discrepancy rule.
  bool stopped_by_held_out = false;
  solvers::tomography::ProjectorSummary projector;
  solvers::tomography::ReconstructionSummary reconstruction;
  Eigen::VectorXf sigma;  // 1/mm, VolumeGrid::Index order
  // Relative L2 error against the phantom averaged over each voxel, inside
  // the cylinder every view sees (radius: half the detector width).
  std::optional<double> relative_error_vs_truth;
  std::optional<CaptureVerdict> capture;  // TomographyInput::capture
  Provenance provenance;                   // the request and the input it was solved from
  double absorbance_ms = 0.0, total_ms = 0.0;  // the centre's estimate and the held-out solve in their summaries

  // kSuccess only: a stopping rule ended it within the noise (the
  // discrepancy rule, a stall within 1.5 x the noise level). An iteration
  // limit (residual above the noise) or inconsistent data is not to be trusted.
  bool trusted() const { return reconstruction.termination == solvers::core::Termination::kSuccess; }
  nlohmann::json ToJson() const;  // report.json
};

// Absorbance, the ring filter (request.ring_filter), the centre of rotation
// (estimated unless request.cor_offset_mm gives it; a failed estimate fails
// the solve, saying to give it), the held-out residual (request.held_out),
// then the solve. Throws std::invalid_argument for a request the solver
// refuses or a volume that does not fit the scan. Failed solves come back in
// the summaries.
TomographyResult SolveTomography(const TomographyInput& input, const config::TomographyRequest& request,
                                 const SystemMatrixFactory& factory = InProcessSystemMatrix());

// volume.nrrd, volume.vdb (where built with OpenVDB: vdb_volume.h),
// report.json, geometry.json and PNG previews of the central slices
// (slice_z.png, slice_y.png, and truth_z.png beside them when the phantom is
// known), into `destination`, replaced whole as it ends (results_folder.h); a
// write that fails throws ResultsWriteError and leaves `destination` as it was.
void WriteTomographyResults(const TomographyInput& input, const TomographyResult& result, const std::string& destination);

}  // namespace photorig::daemon
