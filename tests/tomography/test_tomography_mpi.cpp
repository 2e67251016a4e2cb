// The tomography solver distributed over MPI processes
// (solvers/tomography_mpi, `photorig solve tomography --mpi`) gives the
// single-process solve: the same iterations, the same stop, volumes equal up
// to the order in which floats are summed. mpirun is started by the test, two
// processes on this machine (as root in CI: --allow-run-as-root; without ssh:
// the isolated launcher).

#include "../daemon/test_support.h"
#include "simulated_scan.h"
#include "photorig/daemon/tomography_pipeline.h"
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
  tomography::VolumeGrid grid;
  Eigen::VectorXf sigma;
  EXPECT_TRUE(tomography::ReadNrrd(nrrd.string(), &grid, &sigma).IsSolutionUsable()) << nrrd;
  return sigma;
}

TEST(TomographyMpi, ViewBlocksCoverTheScanOnceInOrder) {
  for (int ranks : {1, 2, 3, 7})
    for (int views : {7, 64, 181}) {
      int next = 0;
      for (int rank = 0; rank < ranks; ++rank) {
        const tomography::mpi::ViewBlock block = tomography::mpi::ViewsOfRank(views, rank, ranks);
        EXPECT_EQ(block.first, next);
        EXPECT_GE(block.count, views / ranks);
        EXPECT_LE(block.count, views / ranks + 1);
        next += block.count;
      }
      EXPECT_EQ(next, views) << ranks << " ranks";
    }
}

TEST(TomographyMpi, TwoProcessesGiveTheSingleProcessSolve) {
  TempDir dir;
  const Outcome probe = Shell(kMpirun + "true", dir);
  if (probe.exit_code != 0) GTEST_SKIP() << "mpirun cannot start two processes here: " << probe.err;

  const TomographyInput input = SimulatedScan();
  const std::string folder = (dir.path() / "scan").string();
  WriteProjectionFolder(input, folder);

  // SIRT: 1e-5 as asked. CGLS: its recurrences (r -= alpha q, p = s + beta p)
  // in float carry the last-bit differences of each back projection forward
  // and the normal equations' conditioning amplifies them; measured 1.8e-3 on
  // this scan at its 8 iterations (docs/tomography.md), hence 1e-2.
  const std::map<std::string, double> bound = {{"sirt", 1e-5}, {"cgls", 1e-2}};
  for (const char* method : {"sirt", "cgls"}) {
    const std::string one = (dir.path() / (std::string(method) + "-1")).string();
    const std::string two = (dir.path() / (std::string(method) + "-2")).string();
    const std::string arguments = " solve tomography --projections " + folder + " --method " + method + " --json";
    const Outcome single = Shell(kEnvironment + Photorig() + arguments + " --out " + one, dir);
    ASSERT_EQ(single.exit_code, 0) << single.err;
    const Outcome distributed = Shell(kMpirun + Photorig() + arguments + " --mpi --out " + two, dir);
    ASSERT_EQ(distributed.exit_code, 0) << distributed.err;
    // The first process alone prints the document.
    const json a = json::parse(single.out), b = json::parse(distributed.out, nullptr, false);
    ASSERT_TRUE(b.is_object()) << "stdout of mpirun: " << distributed.out;
    EXPECT_EQ(b["processes"], 2);
    EXPECT_EQ(a["processes"], 1);
    EXPECT_EQ(a["iterations"], b["iterations"]) << method;
    EXPECT_EQ(a["stop_reason"], b["stop_reason"]) << method;
    EXPECT_EQ(a["rays_used"], b["rays_used"]);
    EXPECT_NEAR(a["residual"].get<double>(), b["residual"].get<double>(), bound.at(method) * a["residual"].get<double>());
    const Eigen::VectorXf x1 = Volume(fs::path(one) / "volume.nrrd"), x2 = Volume(fs::path(two) / "volume.nrrd");
    ASSERT_EQ(x1.size(), x2.size());
    const double relative = (x1 - x2).norm() / x1.norm();
    EXPECT_LT(relative, bound.at(method)) << method;
    std::printf("%s: %d iterations in both, relative difference of the volumes %.3g\n", method,
                a["iterations"].get<int>(), relative);
  }
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
