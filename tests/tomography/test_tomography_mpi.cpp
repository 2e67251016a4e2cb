// The tomography solver distributed over MPI processes
// (solvers/tomography_mpi, `photorig solve tomography --mpi`), split by views
// or by slabs of the volume, gives the single-process solve: the same
// iterations, the same stop, volumes equal up to the order in which floats
// are summed. mpirun is started by the test, two
// processes on this machine (as root in CI: --allow-run-as-root; without ssh:
// the isolated launcher).

#include "../daemon/test_support.h"
#include "simulated_scan.h"
#include "photorig/daemon/pipelines/tomography_pipeline.h"
#include "photorig/sim/phantom.h"
#include "photorig/solvers/tomography/nrrd.h"
#include "photorig/solvers/tomography_mpi/distributed_projector.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using photorig::testing::ReadText;
using photorig::testing::TempDir;

struct Outcome {
  int exit_code = -1;
  std::string out, err;
};

Outcome Shell(const std::string& command, const TempDir& dir) {
  static int calls = 0;
  const fs::path out = dir.path() / ("out" + std::to_string(calls)), err = dir.path() / ("err" + std::to_string(calls));
  ++calls;
  const int status = std::system((command + " > " + out.string() + " 2> " + err.string() + " < /dev/null").c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ReadText(out), ReadText(err)};
}

// One OpenMP thread a process: two processes share the two cores.
const std::string kEnvironment =
    "OMP_NUM_THREADS=1 OMPI_MCA_plm=isolated OMPI_MCA_rmaps_base_oversubscribe=1 "
    "OMPI_MCA_btl_vader_single_copy_mechanism=none ";
const std::string kMpirun = kEnvironment + "mpirun --allow-run-as-root --oversubscribe -np 2 ";

std::string Photorig() { return std::string(PHOTORIG_BIN_DIR) + "/photorig"; }

Eigen::VectorXf Volume(const fs::path& nrrd) {
  solvers::tomography::VolumeGrid grid;
  Eigen::VectorXf sigma;
  EXPECT_TRUE(solvers::tomography::ReadNrrd(nrrd.string(), &grid, &sigma).IsSolutionUsable()) << nrrd;
  return sigma;
}

TEST(TomographyMpi, BlocksCoverTheItemsOnceInOrder) {
  for (int ranks : {1, 2, 3, 7})
    for (int views : {7, 64, 181}) {
      int next = 0;
      for (int rank = 0; rank < ranks; ++rank) {
        const solvers::tomography_mpi::Block block = solvers::tomography_mpi::BlockOfRank(views, rank, ranks);
        EXPECT_EQ(block.first, next);
        EXPECT_GE(block.count, views / ranks);
        EXPECT_LE(block.count, views / ranks + 1);
        next += block.count;
      }
      EXPECT_EQ(next, views) << ranks << " ranks";
    }
}

TEST(TomographyMpi, DecompositionIsCheckedAndChosenFromTheVolumeBudget) {
  using solvers::tomography_mpi::ChooseDecomposition;
  using solvers::tomography_mpi::Decomposition;
  using solvers::tomography_mpi::DecompositionOptions;
  const solvers::tomography::VolumeGrid grid{64, 64, 8, 0.5};
  DecompositionOptions options;
  Decomposition chosen;
  std::string why;
  // 4 volume vectors of 64 x 64 x 8 floats: 512 KiB.
  ASSERT_TRUE(ChooseDecomposition(grid, 64, 4, options, &chosen, &why)) << why;
  EXPECT_EQ(chosen.view_groups, 4);
  EXPECT_EQ(chosen.slabs, 1);
  options.volume_budget_bytes = 300 << 10;  // two slabs of 256 KiB fit
  ASSERT_TRUE(ChooseDecomposition(grid, 64, 4, options, &chosen, &why)) << why;
  EXPECT_EQ(chosen.view_groups, 2);
  EXPECT_EQ(chosen.slabs, 2);
  options.volume_budget_bytes = 1;  // nothing fits: as many slabs as can be
  ASSERT_TRUE(ChooseDecomposition(grid, 64, 12, options, &chosen, &why)) << why;
  EXPECT_EQ(chosen.slabs, 6);  // 12 would be more than the 8 slices
  EXPECT_EQ(chosen.view_groups, 2);

  options.slabs = 3;
  EXPECT_FALSE(ChooseDecomposition(grid, 64, 4, options, &chosen, &why));
  EXPECT_NE(why.find("must divide"), std::string::npos) << why;
  options.slabs = 16;
  EXPECT_FALSE(ChooseDecomposition(grid, 64, 16, options, &chosen, &why));
  EXPECT_NE(why.find("at most one slab a slice"), std::string::npos) << why;
  options.slabs = 1;
  EXPECT_FALSE(ChooseDecomposition(grid, 3, 4, options, &chosen, &why));
  EXPECT_NE(why.find("cannot share 3 views"), std::string::npos) << why;
  options.slabs = -1;
  EXPECT_FALSE(ChooseDecomposition(grid, 64, 4, options, &chosen, &why));
  EXPECT_NE(why.find("slabs must be >= 0"), std::string::npos) << why;
}

// Solves the scan with `solve_flags` in one process and under `mpirun -np 2`
// with `mpi_flags` too, and compares the two.
void ExpectTwoProcessesGiveTheSingleProcessSolve(solvers::tomography::Beam beam, const std::string& solve_flags,
                                                 const std::string& mpi_flags, int view_groups, int slabs) {
  TempDir dir;
  const Outcome probe = Shell(kMpirun + "true", dir);
  if (probe.exit_code != 0) GTEST_SKIP() << "mpirun cannot start two processes here: " << probe.err;

  const TomographyInput input = SimulatedScan(64, beam);
  const std::string folder = (dir.path() / "scan").string();
  WriteProjectionFolder(input, folder);

  // SIRT: 1e-5 as asked. CGLS: its recurrences (r -= alpha q, p = s + beta p)
  // in float carry the last-bit differences of each product forward and the
  // normal equations' conditioning amplifies them; measured up to 1.8e-3 on
  // this scan at its 8 iterations (docs/tomography.md), hence 1e-2.
  const std::map<std::string, double> bound = {{"sirt", 1e-5}, {"cgls", 1e-2}};
  for (const char* method : {"sirt", "cgls"}) {
    const std::string one = (dir.path() / (std::string(method) + "-1")).string();
    const std::string two = (dir.path() / (std::string(method) + "-2")).string();
    const std::string arguments =
        " solve tomography --projections " + folder + " --method " + method + " " + solve_flags + " --json";
    const Outcome single = Shell(kEnvironment + Photorig() + arguments + " --out " + one, dir);
    ASSERT_EQ(single.exit_code, 0) << single.err;
    const Outcome distributed = Shell(kMpirun + Photorig() + arguments + " --mpi " + mpi_flags + " --out " + two, dir);
    ASSERT_EQ(distributed.exit_code, 0) << distributed.err;
    // The first process alone prints the document.
    const json a = json::parse(single.out), b = json::parse(distributed.out, nullptr, false);
    ASSERT_TRUE(b.is_object()) << "stdout of mpirun: " << distributed.out;
    EXPECT_EQ(b["processes"], 2);
    EXPECT_EQ(a["processes"], 1);
    EXPECT_EQ(b["view_groups"], view_groups);
    EXPECT_EQ(b["slabs"], slabs);
    EXPECT_EQ(a["iterations"], b["iterations"]) << method;
    EXPECT_EQ(a["stop_reason"], b["stop_reason"]) << method;
    EXPECT_EQ(a["rays_used"], b["rays_used"]);
    EXPECT_NEAR(a["residual"].get<double>(), b["residual"].get<double>(), bound.at(method) * a["residual"].get<double>());
    const Eigen::VectorXf x1 = Volume(fs::path(one) / "volume.nrrd"), x2 = Volume(fs::path(two) / "volume.nrrd");
    ASSERT_EQ(x1.size(), x2.size());
    const double relative = (x1 - x2).norm() / x1.norm();
    EXPECT_LT(relative, bound.at(method)) << method;
    std::printf("%s, %d view groups x %d slabs: %d iterations in both, relative difference of the volumes %.3g\n",
                method, view_groups, slabs, a["iterations"].get<int>(), relative);
  }
}

TEST(TomographyMpi, TwoProcessesSplittingTheViewsGiveTheSingleProcessSolve) {
  ExpectTwoProcessesGiveTheSingleProcessSolve(solvers::tomography::Beam::kParallel, "", "", 2, 1);
}

// Each process holds four of the eight slices: partial ray sums added over
// the processes, every sum over voxels too, the slabs gathered for writing.
// A cone beam, so that rays cross from one slab into the other (a parallel
// beam's rays each stay in one slice). Its grid of the detector's pitch
// leaves a model error of 1.56 x the noise level after 300 SIRT iterations,
// hence the discrepancy factor 1.8.
TEST(TomographyMpi, TwoProcessesSplittingTheVolumeInSlabsGiveTheSingleProcessSolve) {
  ExpectTwoProcessesGiveTheSingleProcessSolve(solvers::tomography::Beam::kCone, "--discrepancy-factor 1.8", "--mpi-slabs 2", 1,
                                              2);
}

TEST(TomographyMpi, SlabsThatDoNotDivideTheProcessesAreRefusedSayingWhy) {
  TempDir dir;
  const Outcome probe = Shell(kMpirun + "true", dir);
  if (probe.exit_code != 0) GTEST_SKIP() << "mpirun cannot start two processes here: " << probe.err;
  const std::string folder = (dir.path() / "scan").string();
  WriteProjectionFolder(SimulatedScan(8), folder);
  const Outcome outcome =
      Shell(kMpirun + Photorig() + " solve tomography --projections " + folder + " --mpi --mpi-slabs 3 --json", dir);
  EXPECT_EQ(outcome.exit_code, 2);
  EXPECT_NE(outcome.out.find("the slabs must divide them"), std::string::npos) << outcome.out << outcome.err;
}

TEST(TomographyMpi, ArtIsRefusedUnderMpiSayingWhy) {
  TempDir dir;
  const Outcome probe = Shell(kMpirun + "true", dir);
  if (probe.exit_code != 0) GTEST_SKIP() << "mpirun cannot start two processes here: " << probe.err;
  const Outcome outcome =
      Shell(kMpirun + Photorig() + " solve tomography --projections " + dir.path().string() + " --method art --mpi --json",
            dir);
  EXPECT_EQ(outcome.exit_code, 2);
  EXPECT_NE(outcome.out.find("ART visits one ray at a time"), std::string::npos) << outcome.out << outcome.err;
}

}  // namespace
}  // namespace photorig::daemon
