#include "photorig/solvers/brdf/fit.h"
#include "photorig/solvers/brdf/measured.h"
#include "photorig/solvers/brdf/merl.h"
#include "photorig/solvers/brdf/models.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>
#include <random>
#include <sstream>

namespace photorig::solvers::brdf {
namespace {

constexpr double kDeg = M_PI / 180.0;

// Unique to this process: CTest runs each test as a process of its own, two
// at a time, and tests of one fixture write files of the same name.
std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("photorig_brdf_" + std::to_string(::getpid()) + "_" + name)).string();
}

std::vector<char> Bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

ModelParams Ggx() {
  ModelParams p;
  p.model = Model::kGgx;
  p.diffuse = {0.3, 0.2, 0.1};
  p.specular = {0.9, 0.7, 0.5};
  p.shape = 0.2;
  return p;
}

// One table for the whole suite: sampling 1.46 million cells takes a while.
const MerlTable& GgxTable() {
  static const MerlTable table =
      MerlTable::FromFunction([](const DirectionPair& d) { return Evaluate(Ggx(), d.wi, d.wo); });
  return table;
}

TEST(MerlLayout, SizesAndIndexFromTheFileFormat) {
  EXPECT_EQ(MerlTable::kCells, 1458000u);
  EXPECT_EQ(MerlTable::kFileBytes, 34992012u);
  EXPECT_EQ(MerlTable::CellIndex(0, 0, 0), 0u);
  EXPECT_EQ(MerlTable::CellIndex(1, 2, 3), 3u + 180u * 2u + 16200u * 1u);
  EXPECT_EQ(MerlTable::CellIndex(89, 89, 179), MerlTable::kCells - 1);
}

TEST(MerlLayout, BinsHandComputed) {
  // theta_h: floor(90 sqrt(theta_h / 90 deg)); 22.5 deg is a quarter of 90 -> sqrt = 1/2 -> 45.
  EXPECT_EQ(MerlTable::ThetaHBin(0.0), 0);
  EXPECT_EQ(MerlTable::ThetaHBin(-0.1), 0);
  EXPECT_EQ(MerlTable::ThetaHBin(22.5 * kDeg), 45);
  EXPECT_EQ(MerlTable::ThetaHBin(22.4 * kDeg), 44);
  EXPECT_EQ(MerlTable::ThetaHBin(1.0 * kDeg), 9);  // 90 sqrt(1/90) = 9.49
  EXPECT_EQ(MerlTable::ThetaHBin(90.0 * kDeg), 89);  // clamped
  // theta_d: one bin per degree.
  EXPECT_EQ(MerlTable::ThetaDBin(45.5 * kDeg), 45);
  EXPECT_EQ(MerlTable::ThetaDBin(95.0 * kDeg), 89);
  // phi_d: one bin per degree of [0, 180); negative angles folded by adding 180 deg.
  EXPECT_EQ(MerlTable::PhiDBin(10.5 * kDeg), 10);
  EXPECT_EQ(MerlTable::PhiDBin(-90.5 * kDeg), 89);
  EXPECT_EQ(MerlTable::PhiDBin(M_PI), 179);  // clamped
  // Bin centres fall in their own bins.
  for (int i : {0, 1, 44, 89}) {
    const HalfDiff c = MerlTable::CellCentre(i, i, 2 * i);
    EXPECT_EQ(MerlTable::ThetaHBin(c.theta_h), i);
    EXPECT_EQ(MerlTable::ThetaDBin(c.theta_d), i);
    EXPECT_EQ(MerlTable::PhiDBin(c.phi_d), 2 * i);
  }
}

TEST(MerlTable, EvaluationMatchesTheModelAtBinCentres) {
  const MerlTable& table = GgxTable();
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> h(0, 89), d(0, 89), p(0, 179);
  int compared = 0;
  for (int k = 0; k < 2000; ++k) {
    const DirectionPair dirs = FromHalfDiff(MerlTable::CellCentre(h(rng), d(rng), p(rng)), 0.3);
    if (dirs.wi.z() <= 0.0 || dirs.wo.z() <= 0.0) continue;
    const auto value = table.Evaluate(dirs.wi, dirs.wo);
    ASSERT_TRUE(value.has_value());
    const Eigen::Vector3d truth = Evaluate(Ggx(), dirs.wi, dirs.wo);
    EXPECT_LT(((*value - truth).array().abs() / truth.array()).maxCoeff(), 1e-12);
    // At a centre the lookup is the stored cell, bit for bit.
    const HalfDiff a = ToHalfDiff(dirs.wi, dirs.wo);
    const auto cell = table.EvaluateCell(
        MerlTable::CellIndex(MerlTable::ThetaHBin(a.theta_h), MerlTable::ThetaDBin(a.theta_d), MerlTable::PhiDBin(a.phi_d)));
    ASSERT_TRUE(cell.has_value());
    EXPECT_TRUE(*value == *cell);
    ++compared;
  }
  EXPECT_GT(compared, 1000);
}

// A direction that is not finite has no value (it once indexed far outside the table).
TEST(MerlTable, ADirectionThatIsNotFiniteHasNoValue) {
  const MerlTable& table = GgxTable();
  const Eigen::Vector3d up(0.0, 0.0, 1.0), tilted = Eigen::Vector3d(0.3, 0.1, 1.0).normalized();
  for (const double bad : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    EXPECT_FALSE(table.Evaluate(Eigen::Vector3d(bad, 0.0, 1.0), up).has_value());
    EXPECT_FALSE(table.Evaluate(up, Eigen::Vector3d(0.0, bad, 1.0)).has_value());
    EXPECT_FALSE(table.Evaluate(tilted, Eigen::Vector3d(0.0, 0.0, bad)).has_value());
  }
  EXPECT_TRUE(table.Evaluate(tilted, up).has_value());
}

// Between centres the lookup interpolates: against the model it came from,
// several times closer than the nearest cell.
TEST(MerlTable, TrilinearLookupBeatsTheNearestCellBetweenCentres) {
  const MerlTable& table = GgxTable();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> h(0.0, 60.0 * kDeg), d(0.0, 60.0 * kDeg), p(-M_PI, M_PI);
  double trilinear = 0.0, nearest = 0.0;
  int compared = 0;
  for (int k = 0; k < 3000; ++k) {
    const HalfDiff a{h(rng), d(rng), p(rng)};
    const DirectionPair dirs = FromHalfDiff(a, 0.7);
    if (dirs.wi.z() < 0.2 || dirs.wo.z() < 0.2) continue;
    const Eigen::Vector3d truth = Evaluate(Ggx(), dirs.wi, dirs.wo);
    const auto value = table.Evaluate(dirs.wi, dirs.wo);
    const auto cell = table.EvaluateCell(
        MerlTable::CellIndex(MerlTable::ThetaHBin(a.theta_h), MerlTable::ThetaDBin(a.theta_d), MerlTable::PhiDBin(a.phi_d)));
    ASSERT_TRUE(value && cell);
    trilinear += ((*value - truth).array() / truth.array()).square().sum();
    nearest += ((*cell - truth).array() / truth.array()).square().sum();
    ++compared;
  }
  ASSERT_GT(compared, 1000);
  EXPECT_LT(std::sqrt(trilinear / compared), std::sqrt(nearest / compared) / 4.0)
      << "trilinear RMS " << std::sqrt(trilinear / compared) << ", nearest " << std::sqrt(nearest / compared);
}

// An unmeasured neighbour is left out; phi_d wraps around (0 and pi are the
// same configuration by reciprocity).
TEST(MerlTable, TrilinearLookupSkipsUnmeasuredNeighboursAndWrapsPhiD) {
  MerlTable table;
  const int ih = 40, id = 30;
  table.SetCell(MerlTable::CellIndex(ih, id, 0), Eigen::Vector3d(0.1, 0.1, 0.1));
  table.SetCell(MerlTable::CellIndex(ih, id, 179), Eigen::Vector3d(0.3, 0.3, 0.3));
  const HalfDiff centre = MerlTable::CellCentre(ih, id, 0);
  // A quarter of a bin below cell 0's centre in phi_d: three quarters of cell
  // 0 and one of cell 179 (theta_h, theta_d at their centres).
  const double quarter_bin = 0.25 * M_PI / MerlTable::kPhiDBins;
  const DirectionPair wrapped = FromHalfDiff({centre.theta_h, centre.theta_d, centre.phi_d - quarter_bin});
  const auto value = table.Evaluate(wrapped.wi, wrapped.wo);
  ASSERT_TRUE(value.has_value());
  EXPECT_NEAR((*value)[0], 0.75 * 0.1 + 0.25 * 0.3, 1e-9);
  // Without cell 179, only cell 0 remains.
  table.SetCellInvalid(MerlTable::CellIndex(ih, id, 179));
  EXPECT_NEAR((*table.Evaluate(wrapped.wi, wrapped.wo))[0], 0.1, 1e-12);
  // A configuration falling in an unmeasured cell has no value, measured neighbours or not.
  const DirectionPair in_cell_1 = FromHalfDiff({centre.theta_h, centre.theta_d, centre.phi_d + 4.0 * quarter_bin});
  EXPECT_FALSE(table.Evaluate(in_cell_1.wi, in_cell_1.wo).has_value());
}

// A table filled from a model and fitted through the default sampling gives
// the model back (measured: rho_d 0.1-0.2 % high, F0 and a within 0.03 %);
// with the nearest-cell lookup the grid's configurations, which fall between
// cell centres, gave rho_d 10-15 % low.
TEST(MerlTable, FittingATableFilledFromAModelGivesItsDiffuseAlbedoBack) {
  ModelParams truth;
  truth.model = Model::kGgx;
  truth.diffuse = {0.2, 0.15, 0.1};
  truth.specular = {0.9, 0.8, 0.6};
  truth.shape = 0.25;
  const auto table = std::make_shared<MerlTable>(
      MerlTable::FromFunction([&](const DirectionPair& d) { return Evaluate(truth, d.wi, d.wo); }));
  const std::vector<BrdfSample> samples = SampleMeasured(
      [&](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) { return table->Evaluate(wi, wo); }, TableSampling{});
  FitOptions options;
  options.loss = FitLoss::kLog;
  const FitSummary fit = FitModel(Model::kGgx, samples, options);
  ASSERT_TRUE(fit.IsSolutionUsable()) << fit.message;
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(fit.params.diffuse[c], truth.diffuse[c], 0.01 * truth.diffuse[c]) << c;
    EXPECT_NEAR(fit.params.specular[c], truth.specular[c], 0.01 * truth.specular[c]) << c;
  }
  EXPECT_NEAR(fit.params.shape, truth.shape, 0.01 * truth.shape);
}

TEST(MerlTable, NoValueBelowTheHorizonOrInUnmeasuredCells) {
  MerlTable table;  // every cell unmeasured
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ(), down(0.0, 0.6, -0.8);
  EXPECT_FALSE(table.Evaluate(up, up).has_value());
  table.SetCell(MerlTable::CellIndex(0, 0, 0), Eigen::Vector3d(0.1, 0.2, 0.3));
  ASSERT_TRUE(table.Evaluate(up, up).has_value());
  EXPECT_NEAR((*table.Evaluate(up, up))[1], 0.2, 1e-15);
  EXPECT_FALSE(table.Evaluate(up, down).has_value());
  EXPECT_FALSE(table.Evaluate(down, up).has_value());
}

TEST(MerlFile, WriteReadWriteIsByteExact) {
  MerlTable table = GgxTable();
  table.SetCellInvalid(12345);
  const std::string first = TempPath("first.binary"), second = TempPath("second.binary");
  ASSERT_TRUE(WriteMerl(first, table).IsSolutionUsable());
  EXPECT_EQ(std::filesystem::file_size(first), MerlTable::kFileBytes);
  MerlTable read;
  const MerlReadSummary summary = ReadMerl(first, &read);
  ASSERT_EQ(summary.termination, core::Termination::kSuccess) << summary.message;
  EXPECT_GE(summary.invalid_cells, 1u);
  for (int c = 0; c < 3; ++c) EXPECT_TRUE(read.plane(c) == table.plane(c));
  // Evaluated anywhere, the table read back gives the same bits.
  std::mt19937 rng(9);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int k = 0; k < 500; ++k) {
    const Eigen::Vector3d wi = Eigen::Vector3d(g(rng), g(rng), std::abs(g(rng))).normalized();
    const Eigen::Vector3d wo = Eigen::Vector3d(g(rng), g(rng), std::abs(g(rng))).normalized();
    const auto before = table.Evaluate(wi, wo), after = read.Evaluate(wi, wo);
    ASSERT_EQ(before.has_value(), after.has_value());
    if (before) {
      EXPECT_TRUE(*before == *after);
    }
  }
  ASSERT_TRUE(WriteMerl(second, read).IsSolutionUsable());
  EXPECT_TRUE(Bytes(first) == Bytes(second));
  // The header and the first R value as the format defines them.
  const std::vector<char> bytes = Bytes(first);
  std::int32_t dims[3];
  std::memcpy(dims, bytes.data(), sizeof dims);
  EXPECT_EQ(dims[0], 90);
  EXPECT_EQ(dims[1], 90);
  EXPECT_EQ(dims[2], 180);
  double r0;
  std::memcpy(&r0, bytes.data() + 12, sizeof r0);
  EXPECT_NEAR(r0 / 1500.0, (*GgxTable().EvaluateCell(0))[0], 1e-15);
  std::filesystem::remove(first);
  std::filesystem::remove(second);
}

// Writes a file of the right size whose header or body is then spoiled.
std::string SpoiledFile(const std::string& name, std::size_t offset, const void* data, std::size_t size) {
  const std::string path = TempPath(name);
  EXPECT_TRUE(WriteMerl(path, MerlTable()).IsSolutionUsable());
  std::fstream f(path, std::ios::binary | std::ios::in | std::ios::out);
  f.seekp(static_cast<std::streamoff>(offset));
  f.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

void ExpectRefused(const std::string& path, const std::string& what) {
  MerlTable table;
  table.SetCell(0, Eigen::Vector3d::Ones());
  const MerlReadSummary summary = ReadMerl(path, &table);
  EXPECT_EQ(summary.termination, core::Termination::kInvalidInput);
  EXPECT_NE(summary.message.find(path), std::string::npos) << summary.message;
  EXPECT_NE(summary.message.find(what), std::string::npos) << summary.message;
  EXPECT_EQ(table.plane(0)[0], 1500.0) << "a refused read left the table changed";
}

TEST(MerlFile, BadFilesAreRefusedNamingTheFileAndTheFault) {
  ExpectRefused(TempPath("does_not_exist.binary"), "cannot open");

  const std::string short_path = TempPath("short.binary");
  {
    std::ofstream out(short_path, std::ios::binary);
    const std::int32_t dims[3] = {90, 90, 180};
    out.write(reinterpret_cast<const char*>(dims), sizeof dims);
    const double v = 1.0;
    for (int i = 0; i < 1000; ++i) out.write(reinterpret_cast<const char*>(&v), sizeof v);
  }
  ExpectRefused(short_path, "8012 bytes");

  const std::int32_t wrong_dims[3] = {90, 90, 360};
  ExpectRefused(SpoiledFile("header.binary", 0, wrong_dims, sizeof wrong_dims), "header is 90 x 90 x 360");

  const double nan = std::nan("");
  ExpectRefused(SpoiledFile("nan.binary", 12 + 8 * (MerlTable::kCells + 7), &nan, sizeof nan),
                "cell 7 of the G plane is NaN");
  for (const char* name : {"short.binary", "header.binary", "nan.binary"}) std::filesystem::remove(TempPath(name));
}

// A table made from each family, sampled on a 16^3 grid, fitted with the log
// loss, and the choice made (`photorig brdf fit` draws its cells instead:
// test_table_fit.cpp, and the end-to-end tests). The
// table's own family is chosen every time (the simplest model the data
// support), and a richer one whose held-out gain is within the fits' own
// precision (a noise-free table: two Blinn-Phong lobes for one) is not.
struct Family {
  const char* name;
  ModelParams truth;
};

std::vector<Family> Families() {
  auto with = [](Model model, Eigen::Vector3d diffuse, Eigen::Vector3d specular, double shape) {
    ModelParams p;
    p.model = model;
    p.diffuse = diffuse;
    p.specular = specular;
    p.shape = shape;
    return p;
  };
  std::vector<Family> families = {
      {"lambertian", with(Model::kLambertian, {0.5, 0.35, 0.2}, {0, 0, 0}, 0.0)},
      {"blinn_phong", with(Model::kBlinnPhong, {0.25, 0.15, 0.05}, {0.4, 0.3, 0.2}, 60.0)},
      {"ward", with(Model::kWard, {0.25, 0.15, 0.05}, {0.3, 0.25, 0.2}, 0.12)},
      {"ggx with Fresnel", with(Model::kGgx, {0.3, 0.2, 0.1}, {0.9, 0.7, 0.5}, 0.2)},
      // F0 = 1: no Fresnel rise, the lobe's height its scale alone.
      {"ggx without Fresnel", with(Model::kGgx, {0.3, 0.2, 0.1}, {1.0, 1.0, 1.0}, 0.2)},
      // Ngan et al.'s fit to MERL's blue-metallic-paint.
      {"cook_torrance", with(Model::kCookTorrance, {0.0135, 0.00848, 0.0244}, {0.0719, 0.0589, 0.0813}, 0.231)},
      // A sharp coat over a broader, stronger base.
      {"two_blinn_phong", with(Model::kTwoBlinnPhong, {0.2, 0.12, 0.05}, {0.08, 0.08, 0.08}, 400.0)}};
  families[4].truth.specular_scale = 0.3;
  families[5].truth.fresnel_f0 = 0.638;
  families[6].truth.specular2 = {0.3, 0.2, 0.1};
  families[6].truth.shape2 = 12.0;
  return families;
}

TEST(MerlTable, ATableOfEachFamilyChoosesThatFamily) {
  for (const Family& family : Families()) {
    SCOPED_TRACE(family.name);
    const ModelParams& truth = family.truth;
    const MerlTable table = MerlTable::FromFunction([&](const DirectionPair& d) { return Evaluate(truth, d.wi, d.wo); });
    const std::vector<BrdfSample> samples = SampleMeasured(
        [&](const Eigen::Vector3d& wi, const Eigen::Vector3d& wo) { return table.Evaluate(wi, wo); }, TableSampling{});
    SelectionOptions options;
    options.fit.loss = FitLoss::kLog;
    const SelectionSummary s = SelectModel(samples, options);
    ASSERT_EQ(s.termination, core::Termination::kSuccess) << s.message;
    ASSERT_EQ(s.chosen, truth.model) << "chose " << (s.chosen ? ModelName(*s.chosen) : "none") << ": " << s.reason;
    const FitSummary& fit = s.candidates[s.chosen_index];
    EXPECT_EQ(fit.termination, core::Termination::kSuccess);
    std::printf("%s: %s (%s)\n", family.name, ModelName(*s.chosen), s.reason.c_str());
    // Within 1 % and 0.001: the table's trilinear lookup between its cells
    // moves the paint's small albedo (0.0135) by 1.5 %.
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(fit.params.diffuse[c], truth.diffuse[c], 0.01 * truth.diffuse[c] + 0.001) << c;
    if (truth.model == Model::kGgx) {
      EXPECT_NEAR(fit.params.specular_scale, truth.specular_scale, 0.01 * truth.specular_scale);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(fit.params.specular[c], truth.specular[c], 0.01 * truth.specular[c]) << c;
      EXPECT_NEAR(fit.params.shape, truth.shape, 0.01 * truth.shape);
    }
  }
}

// A table ReadMerl would refuse is never written: the first value that is
// not finite is named by plane and bins, and no file appears.
TEST(MerlTable, ATableThatIsNotFiniteIsNotWritten) {
  MerlTable table = MerlTable::FromFunction([](const DirectionPair&) { return Eigen::Vector3d(0.1, 0.1, 0.1); });
  table.plane(1)[MerlTable::CellIndex(10, 20, 30)] = std::nan("");
  const std::string path = TempPath("nan.binary");
  const core::Summary written = WriteMerl(path, table);
  EXPECT_EQ(written.termination, core::Termination::kInvalidInput);
  EXPECT_NE(written.message.find("cell " + std::to_string(MerlTable::CellIndex(10, 20, 30)) +
                                 " of the G plane (theta_h bin 10, theta_d bin 20, phi_d bin 30) is NaN"),
            std::string::npos)
      << written.message;
  EXPECT_FALSE(std::filesystem::exists(path));
}

// The checks ReadMerl makes, on a table of another shape (what the fuzz target reads).
TEST(MerlFile, TheChecksHoldForASmallShape) {
  const std::array<std::int32_t, 3> dims = {1, 2, 2};
  auto bytes = [&](const std::array<std::int32_t, 3>& header, std::vector<double> cells) {
    std::string file(reinterpret_cast<const char*>(header.data()), sizeof header);
    file.append(reinterpret_cast<const char*>(cells.data()), cells.size() * sizeof(double));
    return file;
  };
  auto read = [&](const std::string& file, std::array<std::vector<double>, 3>* planes) {
    std::istringstream in(file);
    return ReadMerlCells(in, file.size(), dims, "t: ", planes);
  };
  std::vector<double> cells(12);
  for (std::size_t i = 0; i < cells.size(); ++i) cells[i] = i == 5 ? -1.0 : 0.25 * static_cast<double>(i);
  std::array<std::vector<double>, 3> planes;
  const MerlReadSummary ok = read(bytes(dims, cells), &planes);
  ASSERT_TRUE(ok.IsSolutionUsable()) << ok.message;
  EXPECT_EQ(planes[0], std::vector<double>(cells.begin(), cells.begin() + 4));
  EXPECT_EQ(planes[2], std::vector<double>(cells.begin() + 8, cells.end()));
  EXPECT_EQ(ok.invalid_cells, 0u);  // the -1 is in the G plane; R's unmeasured cells are counted

  std::array<std::vector<double>, 3> untouched = {std::vector<double>{7.0}};
  EXPECT_EQ(read(bytes(dims, cells).substr(0, 100), &untouched).message,
            "t: 100 bytes, a MERL table has 108 (a 12-byte header and 3 x 4 doubles)");
  EXPECT_EQ(read(bytes({1, 2, 3}, cells), &untouched).message, "t: header is 1 x 2 x 3, not 1 x 2 x 2");
  cells[9] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(read(bytes(dims, cells), &untouched).message, "t: cell 1 of the B plane is infinite");
  EXPECT_EQ(untouched[0], std::vector<double>{7.0}) << "a refused read left the planes changed";
}

}  // namespace
}  // namespace photorig::solvers::brdf
