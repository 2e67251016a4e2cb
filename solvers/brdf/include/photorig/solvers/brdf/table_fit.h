#pragma once
// Fitting a whole measured table so that the error reported is the table's.
//
// The cells are MERL's layout (90 x 90 x 180 in theta_h (square-root bins),
// theta_d, phi_d) whatever the file's format, those with both directions
// within max_theta_deg of the normal and a value in the table. The fits see
// `samples` cells drawn at random with a density that follows the table
// (half uniform over the cells; half in proportion to the squared log
// deviation of f_r cos theta_i from the table's median, which is where its
// lobe and grazing structure are), each weighted by the inverse of its
// density (normalised to mean 1), so that every fit's loss is an unbiased
// estimate of its loss over all cells. `refinement_rounds` times the cells
// are drawn again, half in proportion to the candidates' mean squared
// residual over all cells (where the models fail), and every candidate
// refitted, starting from its previous fit (the draws estimate the same
// loss). The held-out folds, on the last draw only (an earlier draw's choice
// is not used), are whole theta_h bands (each of the 90 theta_h bins in one
// fold, shuffled), so a held-out sample's theta_h level is never in its
// training set.
//
// Every candidate's error is then computed over all cells, in the fit's
// loss (log) and in a loss no candidate was fitted in: the cosine-weighted
// RMS of f_r, sqrt(mean((f_model - f_table)^2 cos^2 theta_i)) in 1/sr.

#include "photorig/solvers/brdf/fit.h"
#include "photorig/solvers/brdf/measured.h"

#include <cstdint>
#include <string>
#include <vector>

namespace photorig::solvers::brdf {

struct TableFitOptions {
  // The model choice; its fit.loss must be kLog (a table carries no deviations).
  SelectionOptions selection = [] {
    SelectionOptions s;
    s.fit.loss = FitLoss::kLog;
    return s;
  }();
  double max_theta_deg = 80.0;  // both directions within this of the normal (tables are least reliable at grazing)
  std::size_t samples = 20000;  // cells drawn per round (FitOptions::max_fit_samples: the fits see them all)
  // The share of each draw that is uniform over the cells: keeps every
  // cell's density above (this / cells), so no weight exceeds 1 / this.
  double uniform_fraction = 0.5;
  int refinement_rounds = 1;  // draws after the first, each where the previous fits erred most
  std::uint32_t seed = 1;     // the draws and the fold shuffle; the same seed gives the same fit
  // The chosen fit's log RMS over all cells above which the table is said
  // to fit no analytic model: 0.05, an error of 5 % in 1 + f_r cos theta_i,
  // beyond a measured table's own accuracy of a few percent.
  double max_log_rms = 0.05;

  bool IsValid(std::string* why) const;
};

// Errors over all cells of a table.
struct CellErrors {
  double log_rms = 0.0;      // RMS of log(1 + f_model cos theta_i) - log(1 + f_table cos theta_i)
  double neutral_rms = 0.0;  // RMS of (f_model - f_table) cos theta_i, 1/sr
};

struct TableFitSummary : core::Summary {
  SelectionSummary selection;  // the last round's candidates and choice
  std::size_t cells = 0;       // valid cells within max_theta_deg
  std::size_t samples = 0;     // samples per round
  // Per candidate (as selection.candidates): the error over all cells; and
  // the ratio of the reported (sample) log RMS to the all-cell one.
  std::vector<CellErrors> all_cells;
  std::vector<double> reported_over_all_cells;
  // The chosen fit fails the table (its all-cell log RMS above
  // max_log_rms): `warning` says so and names the worst region.
  bool poor_fit = false;
  std::string warning;
  // Where the chosen fit's residual is largest: a (theta_h, theta_d) region
  // of 15 x 15 MERL bins (6 x 6 over the quarter circle), and its log RMS.
  double worst_theta_h_deg[2] = {0.0, 0.0};
  double worst_theta_d_deg[2] = {0.0, 0.0};
  double worst_log_rms = 0.0;
};

// Fits `table` as described above. Ends as the selection does (kFailure when
// no candidate is converged, identifiable and plausible), kInvalidInput when
// the table has no valid cell within max_theta_deg.
TableFitSummary FitTable(const MeasuredBrdf& table, const TableFitOptions& options = {});

}  // namespace photorig::solvers::brdf
