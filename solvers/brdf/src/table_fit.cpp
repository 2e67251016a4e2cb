#include "photorig/solvers/brdf/table_fit.h"

#include "photorig/solvers/brdf/merl.h"
#include "photorig/solvers/core/lane_math.h"
#include "photorig/solvers/core/number_text.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>
#include <random>

namespace photorig::solvers::brdf {
namespace {

constexpr int kCellsPerThetaH = MerlTable::kThetaDBins * MerlTable::kPhiDBins;
// The worst-region map: 6 x 6 regions of 15 x 15 bins in (theta_h, theta_d).
constexpr int kRegionBins = 15, kRegions = MerlTable::kThetaHBins / kRegionBins;

// A valid cell: its MERL index, the table's value, the cosines at its centre
// and the table's term of the log loss, log(1 + f_table cos theta_i) per
// channel: each pass over the cells evaluates only the models.
struct Cell {
  std::uint32_t index;
  Eigen::Vector3d value;
  Geometry geometry;
  Eigen::Vector3d log_value;
};

DirectionPair CellDirections(std::uint32_t index) {
  const int ih = static_cast<int>(index / kCellsPerThetaH);
  const int id = static_cast<int>(index / MerlTable::kPhiDBins) % MerlTable::kThetaDBins;
  const int ip = static_cast<int>(index % MerlTable::kPhiDBins);
  return FromHalfDiff(MerlTable::CellCentre(ih, id, ip));
}

int ThetaHBin(std::uint32_t index) { return static_cast<int>(index / kCellsPerThetaH); }
int ThetaDBin(std::uint32_t index) { return static_cast<int>(index / MerlTable::kPhiDBins) % MerlTable::kThetaDBins; }

// Every cell whose centre has both directions within max_theta_deg and a
// finite value in the table, in index order (theta_h bin by theta_h bin). A
// MERL table's value at a cell centre is the stored one (its Evaluate's
// trilinear weights are 1 there), so its cells are read directly: no lookup
// through the directions, and no directions for an unmeasured cell.
std::vector<Cell> ValidCells(const MeasuredBrdf& table, double max_theta_deg) {
  const double min_cos = std::cos(max_theta_deg * M_PI / 180.0);
  const MerlBrdf* merl = table.target<MerlBrdf>();
  std::vector<std::vector<Cell>> per_bin(MerlTable::kThetaHBins);
#pragma omp parallel for schedule(dynamic)
  for (int ih = 0; ih < MerlTable::kThetaHBins; ++ih) {
    // A bin's cells at most: no growth, whose copies and fresh pages cost
    // as much as filling the bin.
    per_bin[ih].reserve(kCellsPerThetaH);
    for (int id = 0; id < MerlTable::kThetaDBins; ++id)
      for (int ip = 0; ip < MerlTable::kPhiDBins; ++ip) {
        const std::size_t index = MerlTable::CellIndex(ih, id, ip);
        std::optional<Eigen::Vector3d> value;
        if (merl && !(value = merl->table->EvaluateCell(index))) continue;
        const DirectionPair d = FromHalfDiff(MerlTable::CellCentre(ih, id, ip));
        if (d.wi.z() <= 0.0 || d.wo.z() <= 0.0 || d.wi.z() < min_cos || d.wo.z() < min_cos) continue;
        if (!merl) value = table(d.wi, d.wo);
        if (!value || !value->allFinite() || (value->array() * d.wi.z() <= -1.0).any()) continue;
        Eigen::Vector3d log_value;
        for (int ch = 0; ch < 3; ++ch) log_value[ch] = std::log1p((*value)[ch] * d.wi.z());
        per_bin[ih].push_back({static_cast<std::uint32_t>(index), *value, GeometryOf(d.wi, d.wo), log_value});
      }
  }
  std::size_t total = 0;
  for (const std::vector<Cell>& bin : per_bin) total += bin.size();
  std::vector<Cell> cells;
  cells.reserve(total);
  for (const std::vector<Cell>& bin : per_bin) cells.insert(cells.end(), bin.begin(), bin.end());
  return cells;
}

// The drawing density over the cells: uniform_fraction uniform, the rest in
// proportion to `score` (uniform alone when every score is zero).
std::vector<double> Density(const std::vector<double>& score, double uniform_fraction) {
  const double total = std::accumulate(score.begin(), score.end(), 0.0);
  const double m = static_cast<double>(score.size());
  const double u = total > 0.0 ? uniform_fraction : 1.0;
  std::vector<double> p(score.size());
  for (std::size_t c = 0; c < p.size(); ++c) p[c] = u / m + (total > 0.0 ? (1.0 - u) * score[c] / total : 0.0);
  return p;
}

// `n` cells drawn with probabilities `p` by systematic sampling in cell order
// (so the draw is stratified over theta_h), each weighted 1 / (cells p): the
// weighted mean of any per-cell quantity over the draw is an unbiased
// estimate of its mean over all cells. `bins` gets each sample's theta_h bin.
std::vector<BrdfSample> Draw(const std::vector<Cell>& cells, const std::vector<double>& p, std::size_t n,
                             std::mt19937* rng, std::vector<int>* bins) {
  std::vector<BrdfSample> samples;
  samples.reserve(n);
  bins->clear();
  const double m = static_cast<double>(cells.size());
  const double offset = std::uniform_real_distribution<double>(0.0, 1.0)(*rng);
  double cumulative = 0.0;
  std::size_t drawn = 0;
  for (std::size_t c = 0; c < cells.size() && drawn < n; ++c) {
    cumulative += p[c] * static_cast<double>(n);
    while (drawn < n && offset + static_cast<double>(drawn) < cumulative) {
      const DirectionPair d = CellDirections(cells[c].index);
      BrdfSample s;
      s.wi = d.wi;
      s.wo = d.wo;
      s.value = cells[c].value;
      s.weight = 1.0 / (m * p[c]);
      samples.push_back(s);
      bins->push_back(ThetaHBin(cells[c].index));
      ++drawn;
    }
  }
  return samples;
}

// Every usable candidate's squared errors over all cells: sums of the log
// and neutral squared residuals, each cell's mean log squared residual over
// the candidates (the next draw's score), and region_candidate's per region.
struct Pass {
  std::vector<double> log_sum, neutral_sum;
  std::vector<double> cell_score;
  double region_sum[kRegions][kRegions] = {};
  double region_count[kRegions][kRegions] = {};
};

// Cells per block of a pass: a candidate's values over a block (scalar: the
// models' lobes), then its log residuals over the block in one `omp simd`
// loop, since glibc's log1p does not vectorise.
constexpr std::size_t kBlockCells = 256;

// Per cell of a block: the squared log residuals summed over the channels,
// sum_ch (log_one_plus(arg[ch]) - log_value[ch])^2, into log2 and added to
// score; returns their sum. Inlined into its callers, so that the lanes'
// version is built for each instruction set LaneLogSquares is.
template <typename LogOnePlus>
PHOTORIG_LANE_INLINE double LogSquares(std::size_t count, const double (*arg)[kBlockCells],
                                       const double (*log_value)[kBlockCells], double* log2, double* score,
                                       const LogOnePlus& log_one_plus) {
  double total = 0.0;
#pragma omp simd reduction(+ : total)
  for (std::size_t i = 0; i < count; ++i) {
    double sum = 0.0;
    for (int ch = 0; ch < 3; ++ch) {
      const double r = log_one_plus(arg[ch][i]) - log_value[ch][i];
      sum += r * r;
    }
    log2[i] = sum;
    score[i] += sum;
    total += sum;
  }
  return total;
}

// LogSquares with the lanes' log, for finite arguments in [2^-1022, 2^1022].
// Multi-versioned (not a template: target_clones takes none): 4 or 8 lanes
// where the CPU has AVX2 or AVX-512, 2 at the baseline.
PHOTORIG_LANE_MULTIVERSION double LaneLogSquares(std::size_t count, const double (*arg)[kBlockCells],
                                                 const double (*log_value)[kBlockCells], double* log2, double* score) {
  return LogSquares(count, arg, log_value, log2, score, [](double x) {
    double unused;
    return core::LaneLogAndInverse(1.0 + x, &unused);
  });
}

Pass ErrorsOverCells(const std::vector<Cell>& cells, const SelectionSummary& selection,
                     std::optional<std::size_t> region_candidate) {
  const std::size_t k = selection.candidates.size();
  std::vector<std::size_t> usable;
  for (std::size_t c = 0; c < k; ++c)
    if (selection.candidates[c].IsSolutionUsable()) usable.push_back(c);
  Pass pass;
  pass.log_sum.assign(k, 0.0);
  pass.neutral_sum.assign(k, 0.0);
  pass.cell_score.assign(cells.size(), 0.0);
  const auto blocks = static_cast<std::ptrdiff_t>((cells.size() + kBlockCells - 1) / kBlockCells);
#pragma omp parallel
  {
    Pass local;
    local.log_sum.assign(k, 0.0);
    local.neutral_sum.assign(k, 0.0);
    double arg[3][kBlockCells], log_value[3][kBlockCells], log2[kBlockCells];
#pragma omp for schedule(static)
    for (std::ptrdiff_t b = 0; b < blocks; ++b) {
      const std::size_t first = static_cast<std::size_t>(b) * kBlockCells;
      const std::size_t count = std::min(kBlockCells, cells.size() - first);
      for (std::size_t i = 0; i < count; ++i)
        for (int ch = 0; ch < 3; ++ch) log_value[ch][i] = cells[first + i].log_value[ch];
      double* score = &pass.cell_score[first];
      for (std::size_t c : usable) {
        // f cos theta_i per channel, and the neutral squared residuals.
        double neutral2 = 0.0;
        bool in_lane_range = true;
        for (std::size_t i = 0; i < count; ++i) {
          const Cell& cell = cells[first + i];
          const double cos_i = cell.geometry.cos_i;
          const Eigen::Vector3d f = EvaluateAt(selection.candidates[c].params, cell.geometry);
          for (int ch = 0; ch < 3; ++ch) {
            arg[ch][i] = f[ch] * cos_i;
            const double q = (f[ch] - cell.value[ch]) * cos_i;
            neutral2 += q * q;
            in_lane_range &= arg[ch][i] >= 0.0 && arg[ch][i] < 0x1p1000;
          }
        }
        // The lanes' log holds for finite arguments in [2^-1022, 2^1022]: a
        // block with a value outside (an infinite or NaN model value) takes
        // log1p, so that the error says so.
        const double log_sum =
            in_lane_range ? LaneLogSquares(count, arg, log_value, log2, score)
                          : LogSquares(count, arg, log_value, log2, score, [](double x) { return std::log1p(x); });
        local.log_sum[c] += log_sum;
        local.neutral_sum[c] += neutral2;
        if (region_candidate && c == *region_candidate)
          for (std::size_t i = 0; i < count; ++i) {
            const std::uint32_t index = cells[first + i].index;
            const int h = ThetaHBin(index) / kRegionBins, t = ThetaDBin(index) / kRegionBins;
            local.region_sum[h][t] += log2[i] / 3.0;
            local.region_count[h][t] += 1.0;
          }
      }
      if (!usable.empty())
        for (std::size_t i = 0; i < count; ++i) score[i] /= static_cast<double>(usable.size());
    }
#pragma omp critical
    {
      for (std::size_t c = 0; c < k; ++c) {
        pass.log_sum[c] += local.log_sum[c];
        pass.neutral_sum[c] += local.neutral_sum[c];
      }
      for (int h = 0; h < kRegions; ++h)
        for (int t = 0; t < kRegions; ++t) {
          pass.region_sum[h][t] += local.region_sum[h][t];
          pass.region_count[h][t] += local.region_count[h][t];
        }
    }
  }
  return pass;
}

std::string Number(double v) { return core::NumberText(v, 3); }

}  // namespace

bool TableFitOptions::IsValid(std::string* why) const {
  if (!selection.IsValid(why)) return false;
  if (selection.fit.loss != FitLoss::kLog) return core::Refuse(why, "a table carries no deviations: fit it with the log loss");
  if (!selection.folds.empty()) return core::Refuse(why, "selection.folds is set by the table fit (theta_h bands)");
  if (!(max_theta_deg > 0.0 && max_theta_deg <= 90.0)) return core::Refuse(why, "max_theta_deg must lie in (0, 90]");
  if (samples < 100) return core::Refuse(why, "samples must be at least 100");
  if (!(uniform_fraction > 0.0 && uniform_fraction <= 1.0)) return core::Refuse(why, "uniform_fraction must lie in (0, 1]");
  if (refinement_rounds < 0) return core::Refuse(why, "refinement_rounds must be non-negative");
  if (!(max_log_rms > 0.0)) return core::Refuse(why, "max_log_rms must be positive");
  return true;
}

TableFitSummary FitTable(const MeasuredBrdf& table, const TableFitOptions& options) {
  core::SolveTimer timer;
  TableFitSummary summary;
  if (core::EndIfInvalid(options, &summary)) return summary;
  const std::vector<Cell> cells = ValidCells(table, options.max_theta_deg);
  summary.cells = cells.size();
  summary.samples = options.samples;
  if (cells.empty()) {
    summary.End(core::Termination::kInvalidInput,
                "the table has no value within " + Number(options.max_theta_deg) + " deg of the normal");
    return summary;
  }
  for (int ch = 0; ch < 3; ++ch)
    if (std::none_of(cells.begin(), cells.end(), [ch](const Cell& c) { return c.value[ch] > 0.0; })) {
      summary.End(core::Termination::kInvalidInput, std::string("the table's ") + "RGB"[ch] +
                                                        " plane within " + Number(options.max_theta_deg) +
                                                        " deg of the normal has no value above 0: it reflects nothing to fit");
      return summary;
    }
  // The first draw's score: the squared log deviation of f cos theta_i from
  // the table's median (per channel), large on the lobe and where the table
  // changes towards grazing, small where it is flat.
  Eigen::Vector3d median;
  for (int ch = 0; ch < 3; ++ch) {
    std::vector<double> values(cells.size());
    for (std::size_t c = 0; c < cells.size(); ++c) values[c] = cells[c].value[ch];
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
    median[ch] = values[values.size() / 2];
  }
  std::vector<double> score(cells.size());
  for (std::size_t c = 0; c < cells.size(); ++c) {
    double s = 0.0;
    for (int ch = 0; ch < 3; ++ch) {
      const double r = cells[c].log_value[ch] - std::log1p(median[ch] * cells[c].geometry.cos_i);
      s += r * r;
    }
    score[c] = s;
  }
  timer.SetupDone(&summary);

  std::mt19937 rng(options.seed);
  // Whole theta_h bins per fold, the bins shuffled so that each fold spans the range.
  std::vector<int> fold_of_bin(MerlTable::kThetaHBins, 0);
  if (options.selection.held_out_folds > 0) {
    std::vector<int> order(MerlTable::kThetaHBins);
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    for (int j = 0; j < MerlTable::kThetaHBins; ++j) fold_of_bin[order[j]] = j % options.selection.held_out_folds;
  }
  Pass pass;
  for (int round = 0; round <= options.refinement_rounds; ++round) {
    std::vector<int> bins;
    const std::vector<BrdfSample> samples = Draw(cells, Density(score, options.uniform_fraction), options.samples, &rng, &bins);
    SelectionOptions selection = options.selection;
    // A draw before the last only places the next: its choice is not used,
    // so it needs no held-out folds.
    if (round < options.refinement_rounds) selection.held_out_folds = 0;
    if (selection.held_out_folds > 0)
      for (int bin : bins) selection.folds.push_back(fold_of_bin[bin]);
    // A later draw estimates the same all-cell loss as the one before (with
    // less variance where the models erred), so its optimum is near the
    // previous fit's: each candidate starts there, and the grid that found
    // the basin is not needed again.
    if (round > 0)
      for (const FitSummary& previous : summary.selection.candidates)
        selection.starts.push_back(previous.IsSolutionUsable() ? std::optional<ModelParams>(previous.params)
                                                               : std::nullopt);
    summary.selection = SelectModel(samples, selection);
    if (summary.selection.candidates.empty()) break;  // refused before any fit
    pass = ErrorsOverCells(cells, summary.selection,
                           summary.selection.chosen ? std::optional<std::size_t>(summary.selection.chosen_index)
                                                    : std::nullopt);
    score = std::move(pass.cell_score);
  }
  const SelectionSummary& s = summary.selection;
  summary.termination = s.termination;
  summary.message = s.message;
  const double values = 3.0 * static_cast<double>(cells.size());
  for (std::size_t c = 0; c < s.candidates.size(); ++c) {
    const FitSummary& f = s.candidates[c];
    const double nan = std::numeric_limits<double>::quiet_NaN();
    if (!f.IsSolutionUsable()) {
      summary.all_cells.push_back({nan, nan});
      summary.reported_over_all_cells.push_back(nan);
      continue;
    }
    const CellErrors e{std::sqrt(pass.log_sum[c] / values), std::sqrt(pass.neutral_sum[c] / values)};
    summary.all_cells.push_back(e);
    summary.reported_over_all_cells.push_back(std::sqrt(f.cost / static_cast<double>(f.residuals)) / e.log_rms);
  }
  // The fit the warning speaks of: the chosen one, or with none chosen the
  // usable candidate with the lowest error over all cells.
  std::optional<std::size_t> reference;
  if (s.chosen) {
    reference = s.chosen_index;
  } else {
    for (std::size_t c = 0; c < summary.all_cells.size(); ++c)
      if (std::isfinite(summary.all_cells[c].log_rms) &&
          (!reference || summary.all_cells[c].log_rms < summary.all_cells[*reference].log_rms))
        reference = c;
  }
  if (reference) {
    const Pass regions = s.chosen ? std::move(pass) : ErrorsOverCells(cells, s, *reference);
    int worst_h = 0, worst_t = 0;
    double worst = -1.0;
    for (int h = 0; h < kRegions; ++h)
      for (int t = 0; t < kRegions; ++t)
        if (regions.region_count[h][t] > 0.0 && regions.region_sum[h][t] / regions.region_count[h][t] > worst) {
          worst = regions.region_sum[h][t] / regions.region_count[h][t];
          worst_h = h;
          worst_t = t;
        }
    auto theta_h_deg = [](int bin) {
      const double u = static_cast<double>(bin) / MerlTable::kThetaHBins;
      return u * u * 90.0;
    };
    summary.worst_theta_h_deg[0] = theta_h_deg(worst_h * kRegionBins);
    summary.worst_theta_h_deg[1] = theta_h_deg((worst_h + 1) * kRegionBins);
    summary.worst_theta_d_deg[0] = worst_t * kRegionBins * 90.0 / MerlTable::kThetaDBins;
    summary.worst_theta_d_deg[1] = (worst_t + 1) * kRegionBins * 90.0 / MerlTable::kThetaDBins;
    summary.worst_log_rms = std::sqrt(std::max(worst, 0.0));
    const double rms = summary.all_cells[*reference].log_rms;
    summary.poor_fit = !s.chosen || rms > options.max_log_rms;
    if (summary.poor_fit)
      summary.warning = "no analytic model fits within " + Number(options.max_log_rms) +
                        " (log RMS over all cells): " +
                        (s.chosen ? std::string("the chosen ") : std::string("none is plausible; the best, ")) +
                        ModelName(s.candidates[*reference].params.model) + ", leaves " + Number(rms) +
                        ", worst at theta_h " + Number(summary.worst_theta_h_deg[0]) + "-" +
                        Number(summary.worst_theta_h_deg[1]) + " deg, theta_d " + Number(summary.worst_theta_d_deg[0]) +
                        "-" + Number(summary.worst_theta_d_deg[1]) + " deg (" + Number(summary.worst_log_rms) +
                        "); keep the table as the material (brdf fit --keep-table)";
  }
  timer.Finish(&summary);
  return summary;
}

}  // namespace photorig::solvers::brdf
