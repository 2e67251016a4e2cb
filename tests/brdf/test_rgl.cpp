#include "photorig/solvers/brdf/measured.h"
#include "photorig/solvers/brdf/models.h"
#include "photorig/solvers/brdf/rgl.h"
#include "photorig/solvers/brdf/tensor_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>

namespace photorig::solvers::brdf {
namespace {

constexpr double kDeg = M_PI / 180.0;

// Unique to this process: CTest runs each test as a process of its own, two
// at a time, and tests of one fixture write files of the same name.
std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("photorig_rgl_" + std::to_string(::getpid()) + "_" + name)).string();
}

std::vector<char> Bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void WriteRaw(const std::string& path, const std::vector<char>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

ModelParams Ggx(double roughness) {
  ModelParams p;
  p.model = Model::kGgx;
  p.diffuse = {0.3, 0.2, 0.1};
  p.specular = {0.9, 0.7, 0.5};
  p.shape = roughness;
  return p;
}

Eigen::Vector3d Direction(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

// The relative error of the table against the model over many configurations,
// theta_i and theta_o up to 80 deg, azimuths anywhere: the largest and the RMS
// over channels.
struct Errors {
  double max = 0.0, rms = 0.0;
};
Errors CompareWithModel(const RglBrdf& rgl, const ModelParams& model, int count) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> cos_theta(std::cos(80 * kDeg), 1.0), phi(-M_PI, M_PI);
  Errors e;
  double sum_sq = 0.0;
  int n = 0;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d wi = Direction(std::acos(cos_theta(rng)), phi(rng));
    const Eigen::Vector3d wo = Direction(std::acos(cos_theta(rng)), phi(rng));
    const std::optional<Eigen::Vector3d> table = rgl.Evaluate(wi, wo);
    const Eigen::Vector3d truth = Evaluate(model, wi, wo);
    EXPECT_TRUE(table.has_value());
    if (!table) continue;
    for (int c = 0; c < 3; ++c) {
      const double rel = std::abs((*table)[c] - truth[c]) / truth[c];
      e.max = std::max(e.max, rel);
      sum_sq += rel * rel;
      ++n;
    }
  }
  e.rms = std::sqrt(sum_sq / n);
  return e;
}

RglTabulation Tabulation(int theta_i, int samples, int ndf, double roughness) {
  RglTabulation t;
  t.theta_i_count = theta_i;
  t.sample_resolution = samples;
  t.ndf_resolution = ndf;
  t.ndf_roughness = roughness;
  t.description = "GGX a = " + std::to_string(roughness);
  return t;
}

RglBrdf WriteAndRead(const ModelParams& model, const RglTabulation& tab, const std::string& name) {
  TensorFile file;
  const core::Summary made = TabulateRgl([&](const DirectionPair& d) { return Evaluate(model, d.wi, d.wo); }, tab, &file);
  EXPECT_EQ(made.termination, core::Termination::kSuccess) << made.message;
  const std::string path = TempPath(name);
  EXPECT_EQ(WriteTensorFile(path, file).termination, core::Termination::kSuccess);
  RglBrdf rgl;
  const core::Summary read = ReadRgl(path, &rgl);
  EXPECT_EQ(read.termination, core::Termination::kSuccess) << read.message;
  std::filesystem::remove(path);
  return rgl;
}

TEST(TensorFile, WrittenAndReadBackFieldForField) {
  TensorFile file;
  file.fields.push_back(TensorField::FromFloats("a", {2, 3}, {1, 2, 3, 4, 5, 6.5f}));
  file.fields.push_back(TensorField::FromBytes("text", {5}, {'h', 'e', 'l', 'l', 'o'}));
  file.fields.push_back(TensorField::FromFloats("b", {1}, {-7.25f}));
  const std::string path = TempPath("roundtrip.bsdf");
  ASSERT_EQ(WriteTensorFile(path, file).termination, core::Termination::kSuccess);
  const std::vector<char> bytes = Bytes(path);
  ASSERT_GE(bytes.size(), 18u);
  EXPECT_EQ(std::memcmp(bytes.data(), "tensor_file\0", 12), 0);
  EXPECT_EQ(bytes[12], 1);  // version 1.0
  EXPECT_EQ(bytes[13], 0);
  TensorFile read;
  const core::Summary s = ReadTensorFile(path, &read);
  ASSERT_EQ(s.termination, core::Termination::kSuccess) << s.message;
  ASSERT_EQ(read.fields.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(read.fields[i].name, file.fields[i].name);
    EXPECT_EQ(read.fields[i].type, file.fields[i].type);
    EXPECT_EQ(read.fields[i].shape, file.fields[i].shape);
    EXPECT_EQ(read.fields[i].bytes, file.fields[i].bytes);
  }
  EXPECT_EQ(read.Find("a")->Floats()[5], 6.5f);
  std::filesystem::remove(path);
}

// The warp's inverse undoes its forward map, across a parameter between two
// tabulated slices as well.
TEST(Warp2D, InvertUndoesSample) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const int nx = 7, ny = 5;
  std::vector<double> values(2 * nx * ny);
  for (double& v : values) v = 0.1 + u(rng);
  const Warp2D warp(nx, ny, {{0.0, 1.0}}, values, true);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector2d s(u(rng), u(rng));
    const double param = i % 2 ? 0.0 : u(rng);
    const Eigen::Vector2d back = warp.Invert(warp.Sample(s, {param}), {param});
    EXPECT_NEAR(back.x(), s.x(), 1e-12);
    EXPECT_NEAR(back.y(), s.y(), 1e-12);
  }
}

// A GGX tabulated in its own parameterisation, written, read back and
// evaluated against the model. Between nodes the reader interpolates
// bilinearly in the sample square and in the ndf and sigma grids, and
// linearly across theta_i: errors of second order in the node spacing. At
// 16 incident elevations, a 32 x 32 sample square and 64 x 64 NDF nodes the
// relative error is 1.2 % RMS, 12 % at worst (near grazing, where the visible
// region's edge runs between nodes); doubling every resolution cuts the RMS
// 4.3x (0.28 %, 2 % at worst), as a second-order error should (4x). The test
// asks for those bounds with a margin and a cut of at least 3x.
TEST(RglBrdf, GgxTableMatchesTheModelItWasMadeFrom) {
  const ModelParams model = Ggx(0.3);
  const RglBrdf coarse = WriteAndRead(model, Tabulation(16, 32, 64, 0.3), "ggx_coarse.bsdf");
  EXPECT_EQ(coarse.theta_i_count(), 16);
  EXPECT_EQ(coarse.sample_resolution(), 32);
  EXPECT_EQ(coarse.description(), "GGX a = 0.300000");
  const Errors e_coarse = CompareWithModel(coarse, model, 4000);
  const RglBrdf fine = WriteAndRead(model, Tabulation(32, 64, 128, 0.3), "ggx_fine.bsdf");
  const Errors e_fine = CompareWithModel(fine, model, 4000);
  RecordProperty("coarse_rms", std::to_string(e_coarse.rms));
  RecordProperty("fine_rms", std::to_string(e_fine.rms));
  std::printf("relative error: coarse rms %.4g max %.4g; fine rms %.4g max %.4g\n", e_coarse.rms, e_coarse.max,
              e_fine.rms, e_fine.max);
  EXPECT_LT(e_coarse.rms, 0.02);
  EXPECT_LT(e_coarse.max, 0.15);
  EXPECT_LT(e_fine.max, 0.03);
  EXPECT_LT(e_fine.rms * 3.0, e_coarse.rms);
}

// The parameterisation's NDF need not be the BRDF's: a Lambertian surface
// through a GGX of a = 0.5 comes back as rho / pi.
TEST(RglBrdf, LambertianThroughAnyNdfIsFlat) {
  ModelParams matte;
  matte.model = Model::kLambertian;
  matte.diffuse = {0.8, 0.5, 0.2};
  const RglBrdf rgl = WriteAndRead(matte, Tabulation(16, 32, 64, 0.5), "matte.bsdf");
  const Errors e = CompareWithModel(rgl, matte, 2000);
  std::printf("lambertian relative error: rms %.4g max %.4g\n", e.rms, e.max);
  EXPECT_LT(e.rms, 0.02);
  EXPECT_LT(e.max, 0.15);
  EXPECT_FALSE(rgl.Evaluate(Direction(0.3, 0), Direction(95 * kDeg, 0)).has_value());  // below the horizon
}

// Either format opens behind one evaluation; the samples drawn from it stay
// within the angle limit and carry the table's values.
TEST(MeasuredTable, OpensByExtensionAndSamplesWithinTheLimit) {
  const ModelParams model = Ggx(0.3);
  TensorFile file;
  ASSERT_TRUE(TabulateRgl([&](const DirectionPair& d) { return Evaluate(model, d.wi, d.wo); },
                          Tabulation(4, 8, 16, 0.3), &file)
                  .IsSolutionUsable());
  const std::string path = TempPath("measured.bsdf");
  ASSERT_TRUE(WriteTensorFile(path, file).IsSolutionUsable());
  MeasuredBrdf table;
  ASSERT_TRUE(ReadMeasured(path, &table).IsSolutionUsable());
  RglBrdf direct;
  ASSERT_TRUE(ReadRgl(path, &direct).IsSolutionUsable());
  TableSampling sampling;
  sampling.theta_h_steps = sampling.theta_d_steps = sampling.phi_d_steps = 8;
  const std::vector<BrdfSample> samples = SampleMeasured(table, sampling);
  EXPECT_GT(samples.size(), 200u);
  for (const BrdfSample& s : samples) {
    EXPECT_GE(std::min(s.wi.z(), s.wo.z()), std::cos(80 * kDeg) - 1e-12);
    EXPECT_EQ(s.value, *direct.Evaluate(s.wi, s.wo));
  }
  std::filesystem::remove(path);
  const core::Summary other = ReadMeasured(TempPath("table.txt"), &table);
  EXPECT_EQ(other.termination, core::Termination::kInvalidInput);
  EXPECT_NE(other.message.find("not a measured-BRDF file"), std::string::npos) << other.message;
}

TEST(SamplesCsv, WrittenAndReadBackAndABadLineNamed) {
  std::vector<BrdfSample> samples(2);
  samples[0].wi = Direction(0.3, 0.1);
  samples[0].wo = Direction(0.7, 2.0);
  samples[0].value = {0.1, 0.2, 1.0 / 3.0};
  samples[0].sigma = {0.01, 0.02, 0.03};
  samples[0].origin = SampleOrigin{-35.5, 20.25, 90.0, 4000.0, 6};
  samples[1].value = {5, 6, 7};  // no origin: drawn from a table
  const std::string path = TempPath("samples.csv");
  ASSERT_TRUE(WriteSamplesCsv(path, samples).IsSolutionUsable());
  std::vector<BrdfSample> read;
  const core::Summary s = ReadSamplesCsv(path, &read);
  ASSERT_EQ(s.termination, core::Termination::kSuccess) << s.message;
  ASSERT_EQ(read.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {  // 17 digits: every double comes back exactly
    EXPECT_EQ(read[i].wi, samples[i].wi);
    EXPECT_EQ(read[i].wo, samples[i].wo);
    EXPECT_EQ(read[i].value, samples[i].value);
    EXPECT_EQ(read[i].sigma, samples[i].sigma);
  }
  ASSERT_TRUE(read[0].origin.has_value());
  EXPECT_EQ(read[0].origin->light_arm_deg, -35.5);
  EXPECT_EQ(read[0].origin->camera_arm_deg, 20.25);
  EXPECT_EQ(read[0].origin->sample_rotation_deg, 90.0);
  EXPECT_EQ(read[0].origin->exposure_us, 4000.0);
  EXPECT_EQ(read[0].origin->frames, 6);
  EXPECT_FALSE(read[1].origin.has_value());

  std::ofstream(path, std::ios::app) << "1,2,3\n";
  const core::Summary bad = ReadSamplesCsv(path, &read);
  EXPECT_EQ(bad.termination, core::Termination::kInvalidInput);
  EXPECT_NE(bad.message.find(path + "':4: 3 cells, not 17"), std::string::npos) << bad.message;
  EXPECT_EQ(read.size(), 2u);  // untouched

  // An origin given in part is refused: a pose without its exposure cannot be traced.
  std::ofstream(path, std::ios::trunc)
      << "wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,f_r,f_g,f_b,sigma_r,sigma_g,sigma_b,light_arm_deg,camera_arm_deg,"
         "sample_rotation_deg,exposure_us,frames\n"
      << "0,0,1,0,0,1,1,1,1,0,0,0,10,20,,,\n";
  const core::Summary partial = ReadSamplesCsv(path, &read);
  EXPECT_EQ(partial.termination, core::Termination::kInvalidInput);
  EXPECT_NE(partial.message.find(":2: the origin"), std::string::npos) << partial.message;
  std::filesystem::remove(path);
}

// Files written before the origin columns existed still read.
TEST(SamplesCsv, ReadsTheFileWithoutOriginColumns) {
  const std::string path = TempPath("samples_v1.csv");
  std::ofstream(path) << "wi_x,wi_y,wi_z,wo_x,wo_y,wo_z,f_r,f_g,f_b,sigma_r,sigma_g,sigma_b\n"
                      << "0,0,1,0.6,0,0.8,0.25,0.5,0.75,0.01,0.02,0.03\n";
  std::vector<BrdfSample> read;
  const core::Summary s = ReadSamplesCsv(path, &read);
  ASSERT_EQ(s.termination, core::Termination::kSuccess) << s.message;
  ASSERT_EQ(read.size(), 1u);
  EXPECT_EQ(read[0].value, Eigen::Vector3d(0.25, 0.5, 0.75));
  EXPECT_EQ(read[0].wo, Eigen::Vector3d(0.6, 0, 0.8));
  EXPECT_FALSE(read[0].origin.has_value());
  std::filesystem::remove(path);
}

// ----- Bad files: each refused with the file and the fault named, nothing crashes.

class RglBadFile : public ::testing::Test {
 protected:
  void SetUp() override {
    const ModelParams model = Ggx(0.4);
    ASSERT_EQ(TabulateRgl([&](const DirectionPair& d) { return Evaluate(model, d.wi, d.wo); },
                          Tabulation(3, 4, 8, 0.4), &valid_)
                  .termination,
              core::Termination::kSuccess);
    path_ = TempPath("bad.bsdf");
  }
  void TearDown() override { std::filesystem::remove(path_); }

  // Reads path_ and expects a refusal whose message names the file and `fault`.
  void ExpectRefused(const std::string& fault) {
    RglBrdf rgl;
    const core::Summary s = ReadRgl(path_, &rgl);
    EXPECT_EQ(s.termination, core::Termination::kInvalidInput);
    EXPECT_NE(s.message.find(path_), std::string::npos) << s.message;
    EXPECT_NE(s.message.find(fault), std::string::npos) << s.message;
  }
  std::vector<char> ValidBytes() {
    EXPECT_EQ(WriteTensorFile(path_, valid_).termination, core::Termination::kSuccess);
    return Bytes(path_);
  }
  // Where field `name`'s uint64 offset sits in the header.
  std::size_t OffsetPosition(const std::vector<char>& bytes, const std::string& name) {
    const std::string key = std::string(1, char(name.size())) + '\0' + name;
    const auto it = std::search(bytes.begin(), bytes.end(), key.begin(), key.end());
    EXPECT_NE(it, bytes.end());
    return static_cast<std::size_t>(it - bytes.begin()) + key.size() + 2 + 1;
  }

  TensorFile valid_;
  std::string path_;
};

TEST_F(RglBadFile, TheValidFileReads) {
  ValidBytes();
  RglBrdf rgl;
  const core::Summary s = ReadRgl(path_, &rgl);
  EXPECT_EQ(s.termination, core::Termination::kSuccess) << s.message;
}

TEST_F(RglBadFile, MissingFile) {
  std::filesystem::remove(path_);
  ExpectRefused("cannot open");
}

TEST_F(RglBadFile, WrongMagic) {
  std::vector<char> bytes = ValidBytes();
  bytes[0] = 'T';
  WriteRaw(path_, bytes);
  ExpectRefused("wrong header");
}

TEST_F(RglBadFile, WrongVersion) {
  std::vector<char> bytes = ValidBytes();
  bytes[12] = 2;
  WriteRaw(path_, bytes);
  ExpectRefused("version 2.0");
}

TEST_F(RglBadFile, ShorterThanTheHeader) {
  WriteRaw(path_, {'t', 'e', 'n', 's'});
  ExpectRefused("shorter than the 18-byte header");
}

TEST_F(RglBadFile, ShortBody) {
  std::vector<char> bytes = ValidBytes();
  bytes.resize(bytes.size() - 10);
  WriteRaw(path_, bytes);
  ExpectRefused("beyond the end");
}

TEST_F(RglBadFile, HeaderCutShort) {
  std::vector<char> bytes = ValidBytes();
  bytes.resize(40);
  WriteRaw(path_, bytes);
  ExpectRefused("cut short");
}

TEST_F(RglBadFile, FieldOffsetOutOfRange) {
  std::vector<char> bytes = ValidBytes();
  const std::uint64_t far = std::numeric_limits<std::uint64_t>::max() - 3;
  std::memcpy(bytes.data() + OffsetPosition(bytes, "vndf"), &far, 8);
  WriteRaw(path_, bytes);
  ExpectRefused("'vndf': its data");
}

TEST_F(RglBadFile, UnknownDtype) {
  std::vector<char> bytes = ValidBytes();
  bytes[OffsetPosition(bytes, "ndf") - 1] = 42;
  WriteRaw(path_, bytes);
  ExpectRefused("unknown dtype 42");
}

TEST_F(RglBadFile, WrongTensorDtype) {
  for (TensorField& f : valid_.fields)
    if (f.name == "ndf") {
      const std::vector<float> v = f.Floats();
      f.type = TensorType::kFloat64;
      f.bytes.resize(v.size() * 8);
      for (std::size_t i = 0; i < v.size(); ++i) {
        const double d = v[i];
        std::memcpy(f.bytes.data() + 8 * i, &d, 8);
      }
    }
  ASSERT_EQ(WriteTensorFile(path_, valid_).termination, core::Termination::kSuccess);
  ExpectRefused("field 'ndf' is float64, the format stores float32");
}

TEST_F(RglBadFile, NaNCell) {
  for (TensorField& f : valid_.fields)
    if (f.name == "rgb") {
      const float nan = std::numeric_limits<float>::quiet_NaN();
      std::memcpy(f.bytes.data() + 4 * 17, &nan, 4);
    }
  ASSERT_EQ(WriteTensorFile(path_, valid_).termination, core::Termination::kSuccess);
  ExpectRefused("field 'rgb' cell 17 is NaN");
}

TEST_F(RglBadFile, MissingField) {
  std::erase_if(valid_.fields, [](const TensorField& f) { return f.name == "sigma"; });
  ASSERT_EQ(WriteTensorFile(path_, valid_).termination, core::Termination::kSuccess);
  ExpectRefused("no field 'sigma'");
}

TEST_F(RglBadFile, WrongShape) {
  for (TensorField& f : valid_.fields)
    if (f.name == "luminance") f.shape = {1, 3, 2, 8};  // same count, not square
  ASSERT_EQ(WriteTensorFile(path_, valid_).termination, core::Termination::kSuccess);
  ExpectRefused("field 'luminance' is 1 x 3 x 2 x 8");
}

TEST_F(RglBadFile, SpectralFileIsRefusedSayingWhy) {
  for (TensorField& f : valid_.fields)
    if (f.name == "rgb") f.name = "spectra";
  valid_.fields.push_back(TensorField::FromFloats("wavelengths", {3}, {450, 550, 650}));
  ASSERT_EQ(WriteTensorFile(path_, valid_).termination, core::Termination::kSuccess);
  ExpectRefused("a spectral file");
}

TEST_F(RglBadFile, AnisotropicFileIsRefusedSayingWhy) {
  for (TensorField& f : valid_.fields)
    if (f.name == "phi_i") f = TensorField::FromFloats("phi_i", {3}, {-1, 0, 1});
  ASSERT_EQ(WriteTensorFile(path_, valid_).termination, core::Termination::kSuccess);
  ExpectRefused("anisotropic (3 phi_i values)");
}

TEST_F(RglBadFile, RepeatedField) {
  valid_.fields.push_back(valid_.fields.front());
  ASSERT_EQ(WriteTensorFile(path_, valid_).termination, core::Termination::kSuccess);
  ExpectRefused("appears twice");
}

// A device is refused before a byte is read (/dev/urandom would be read
// until memory ran out), and so is a file beyond the format's size limit.
TEST(TensorFile, ADeviceOrAnOversizedFileIsRefusedUnread) {
  TensorFile file;
  const core::Summary device = ReadTensorFile("/dev/urandom", &file);
  EXPECT_EQ(device.termination, core::Termination::kInvalidInput);
  EXPECT_NE(device.message.find("'/dev/urandom': not a regular file"), std::string::npos) << device.message;
  const std::string huge = TempPath("huge.bsdf");
  std::ofstream(huge).close();
  std::filesystem::resize_file(huge, kMaxTensorFileBytes + 1);  // sparse: no disk used
  const core::Summary oversized = ReadTensorFile(huge, &file);
  std::filesystem::remove(huge);
  EXPECT_EQ(oversized.termination, core::Termination::kInvalidInput);
  EXPECT_NE(oversized.message.find("more than the 256 MiB"), std::string::npos) << oversized.message;
  EXPECT_TRUE(file.fields.empty());
}

// A BRDF whose values leave a float's range makes no table: the value is named
// by its place, as the reader would name it.
TEST(RglBrdf, ATableThatIsNotFiniteIsNotMade) {
  TensorFile file;
  const core::Summary made = TabulateRgl(
      [](const DirectionPair& d) {
        return d.wo.z() > 0.5 ? Eigen::Vector3d(0.1, 1e300, 0.1) : Eigen::Vector3d(0.1, 0.1, 0.1);
      },
      Tabulation(3, 4, 8, 0.4), &file);
  EXPECT_EQ(made.termination, core::Termination::kInvalidInput);
  EXPECT_NE(made.message.find("field 'rgb' cell"), std::string::npos) << made.message;
  EXPECT_NE(made.message.find("channel G"), std::string::npos) << made.message;
  EXPECT_NE(made.message.find("is infinite"), std::string::npos) << made.message;
  EXPECT_TRUE(file.fields.empty());
}

}  // namespace
}  // namespace photorig::solvers::brdf
