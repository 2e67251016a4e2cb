// Fitting a whole table: the samples see a sub-degree lobe, the reported
// error is the error over all cells, the folds are theta_h bands, and a table
// no model fits says so and where.
#include "photorig/solvers/brdf/table_fit.h"

#include "photorig/solvers/brdf/merl.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>

namespace photorig::solvers::brdf {
namespace {

MeasuredBrdf TableOf(const std::function<Eigen::Vector3d(const Eigen::Vector3d&, const Eigen::Vector3d&)>& f) {
  return [f](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) -> std::optional<Eigen::Vector3d> {
    if (wi.z() <= 0.0 || wo.z() <= 0.0) return std::nullopt;
    return f(wi, wo);
  };
}

TableFitOptions Quick(int refinement_rounds) {
  TableFitOptions options;
  options.samples = 4000;
  options.refinement_rounds = refinement_rounds;
  return options;
}

// A lobe 0.6 deg wide (e = 20,000), as the sharpest measured ones: a 16^3
// grid put one theta_h level inside it. The draw finds it, the fit recovers
// it, and the error reported from the samples is the error over all cells.
TEST(TableFit, ASubDegreeLobeIsSeenAndTheReportedErrorIsTheTables) {
  ModelParams truth;
  truth.model = Model::kBlinnPhong;
  truth.diffuse = {0.2, 0.15, 0.1};
  truth.specular = {0.1, 0.1, 0.1};
  truth.shape = 20000.0;
  const TableFitSummary t = FitTable(TableOf([&](const auto& wi, const auto& wo) { return Evaluate(truth, wi, wo); }), Quick(1));
  ASSERT_EQ(t.termination, core::Termination::kSuccess) << t.message;
  const SelectionSummary& s = t.selection;
  ASSERT_EQ(s.chosen, Model::kBlinnPhong) << s.reason;
  const FitSummary& fit = s.candidates[s.chosen_index];
  EXPECT_NEAR(fit.params.shape, truth.shape, 0.01 * truth.shape);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(fit.params.specular[c], truth.specular[c], 0.01 * truth.specular[c]);
  EXPECT_LT(t.all_cells[s.chosen_index].log_rms, 1e-4);
  EXPECT_FALSE(t.poor_fit);
  // Every usable candidate's sample error estimates its all-cell error.
  for (std::size_t c = 0; c < s.candidates.size(); ++c) {
    if (!s.candidates[c].IsSolutionUsable() || t.all_cells[c].log_rms < 1e-3) continue;
    EXPECT_GT(t.reported_over_all_cells[c], 0.8) << ModelName(s.candidates[c].params.model);
    EXPECT_LT(t.reported_over_all_cells[c], 1.25) << ModelName(s.candidates[c].params.model);
  }
  EXPECT_GT(t.cells, 900000u);  // of MERL's 1,458,000, those with both directions within 80 deg
}

// A MERL table as ReadMeasured gives it (MerlBrdf) is read at its cell
// centres directly: the same cells with the same values as through its
// trilinear Evaluate, so the same draw and the same fits. The table has a
// lobe, a ripple that makes every cell's value its own, and unmeasured cells
// (a theta_d band and a scatter).
TEST(TableFit, AMerlTableReadAtItsCellsGivesTheCellsOfItsLookup) {
  ModelParams truth;
  truth.model = Model::kGgx;
  truth.diffuse = {0.3, 0.2, 0.1};
  truth.specular = {0.05, 0.04, 0.03};
  truth.shape = 0.1;
  auto table = std::make_shared<MerlTable>(MerlTable::FromFunction([&](const DirectionPair& d) {
    return std::optional<Eigen::Vector3d>(Evaluate(truth, d.wi, d.wo) * (1.0 + 0.01 * std::sin(1e3 * d.wo.x())));
  }));
  for (int ih = 0; ih < MerlTable::kThetaHBins; ++ih)
    for (int ip = 0; ip < MerlTable::kPhiDBins; ++ip) {
      table->SetCellInvalid(MerlTable::CellIndex(ih, 40, ip));
      table->SetCellInvalid(MerlTable::CellIndex(ih, (ih * 7 + ip) % MerlTable::kThetaDBins, ip));
    }
  const std::shared_ptr<const MerlTable> read_only = table;
  const TableFitSummary direct = FitTable(MerlBrdf{read_only}, Quick(0));
  const TableFitSummary lookup = FitTable(
      [read_only](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) { return read_only->Evaluate(wi, wo); }, Quick(0));
  ASSERT_EQ(direct.termination, core::Termination::kSuccess) << direct.message;
  EXPECT_EQ(direct.cells, lookup.cells);
  EXPECT_LT(direct.cells, 900000u);
  ASSERT_EQ(direct.selection.chosen, lookup.selection.chosen);
  ASSERT_EQ(direct.selection.candidates.size(), lookup.selection.candidates.size());
  for (std::size_t c = 0; c < direct.selection.candidates.size(); ++c) {
    const FitSummary &a = direct.selection.candidates[c], &b = lookup.selection.candidates[c];
    const char* name = ModelName(a.params.model);
    EXPECT_EQ(a.cost, b.cost) << name;
    EXPECT_EQ(a.params.diffuse, b.params.diffuse) << name;
    EXPECT_EQ(a.params.specular, b.params.specular) << name;
    EXPECT_EQ(a.params.shape, b.params.shape) << name;
    if (!a.IsSolutionUsable()) continue;
    // The passes over the cells add per thread in either order: equal to rounding.
    EXPECT_NEAR(direct.all_cells[c].log_rms, lookup.all_cells[c].log_rms, 1e-12 * lookup.all_cells[c].log_rms) << name;
  }
}

// A retro-reflective peak (light back towards the source: theta_d near 0 at
// every theta_h) that no model here has.
MeasuredBrdf RetroReflector(double peak_per_sr) {
  return TableOf([peak_per_sr](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) {
    const double theta_d = std::acos(std::min(1.0, std::sqrt(0.5 * (1.0 + wi.dot(wo)))));
    return Eigen::Vector3d::Constant(0.1 + peak_per_sr * std::exp(-theta_d * theta_d / 0.01));
  });
}

// A model is chosen but fits the table poorly: the table says so and names
// the region (theta_d 0-15 deg).
TEST(TableFit, ATableNoModelFitsSaysSoAndWhere) {
  const TableFitSummary t = FitTable(RetroReflector(0.5), Quick(0));
  ASSERT_TRUE(t.selection.chosen.has_value()) << t.message;
  EXPECT_TRUE(t.poor_fit);
  EXPECT_NE(t.warning.find("no analytic model fits within 0.05"), std::string::npos) << t.warning;
  EXPECT_EQ(t.worst_theta_d_deg[0], 0.0) << t.warning;
  EXPECT_EQ(t.worst_theta_d_deg[1], 15.0) << t.warning;
}

// Stronger, every candidate's albedo exceeds 1 and none is chosen: the table
// still says no model fits, with the best candidate's error and region.
TEST(TableFit, ATableNoPlausibleModelFitsSaysSoToo) {
  const TableFitSummary t = FitTable(RetroReflector(20.0), Quick(0));
  EXPECT_EQ(t.termination, core::Termination::kFailure);
  EXPECT_FALSE(t.selection.chosen.has_value());
  EXPECT_TRUE(t.poor_fit);
  EXPECT_NE(t.warning.find("no analytic model fits within 0.05"), std::string::npos) << t.warning;
  EXPECT_NE(t.warning.find("none is plausible"), std::string::npos) << t.warning;
  EXPECT_EQ(t.worst_theta_d_deg[1], 15.0) << t.warning;
}

TEST(TableFit, OptionsAndAnEmptyTableAreRefused) {
  TableFitOptions options;
  options.selection.fit.loss = FitLoss::kWeighted;
  const MeasuredBrdf flat = TableOf([](const auto&, const auto&) { return Eigen::Vector3d::Constant(0.1); });
  EXPECT_EQ(FitTable(flat, options).termination, core::Termination::kInvalidOptions);
  const MeasuredBrdf empty = [](const Eigen::Vector3d&, const Eigen::Vector3d&) { return std::optional<Eigen::Vector3d>(); };
  EXPECT_EQ(FitTable(empty).termination, core::Termination::kInvalidInput);
}

// Folds given per sample must match the samples.
TEST(TableFit, FoldsMustMatchTheSamples) {
  BrdfSample s;
  s.value = {0.1, 0.1, 0.1};
  SelectionOptions options;
  options.fit.loss = FitLoss::kLog;
  options.folds = {0, 1};
  EXPECT_EQ(SelectModel({s, s, s}, options).termination, core::Termination::kInvalidOptions);
  options.folds = {0, 1, 7};
  EXPECT_EQ(SelectModel({s, s, s}, options).termination, core::Termination::kInvalidOptions);
}

}  // namespace
}  // namespace photorig::solvers::brdf
