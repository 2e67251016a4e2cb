// The Radiance HDR, PNM and BMP decoders against OpenCV's (cv::imdecode,
// IMREAD_UNCHANGED): every file OpenCV writes, and the variants built here,
// decode to the same type, size and bits. The HDR encoder's files read alike
// in OpenCV and here and hold the image to RGBE's precision. Truncated,
// corrupt, unsupported and oversized files are refused with a reason.

#include "formats.h"
#include "photorig/solvers/codecs/image_codecs.h"

#include "same_bits.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace photorig::solvers::codecs::internal {
namespace {

using Bytes = std::vector<std::uint8_t>;
using Decoder = cv::Mat (*)(std::span<const std::uint8_t>, std::string*, std::uint64_t);

Bytes ToBytes(const std::string& text) { return Bytes(text.begin(), text.end()); }

Bytes Encoded(const std::string& extension, const cv::Mat& image, const std::vector<int>& parameters = {}) {
  Bytes bytes;
  EXPECT_TRUE(cv::imencode(extension, image, bytes, parameters)) << extension;
  return bytes;
}

using photorig::solvers::codecs::test_support::SameBits;

// Decoded, with no reason given, to exactly what OpenCV decodes.
::testing::AssertionResult DecodesAsOpenCv(Decoder decode, const Bytes& bytes) {
  std::string why;
  const cv::Mat image = decode(bytes, &why, kMaxDecodedBytes);
  if (image.empty()) return ::testing::AssertionFailure() << "refused: " << why;
  if (!why.empty()) return ::testing::AssertionFailure() << "decoded, yet with a reason: " << why;
  const cv::Mat opencv = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
  if (opencv.empty()) return ::testing::AssertionFailure() << "OpenCV refuses the file";
  return SameBits(image, opencv);
}

// Refused, with a reason that names the format and says `words`.
::testing::AssertionResult Refused(Decoder decode, const Bytes& bytes, const std::string& format,
                                   const std::string& words) {
  std::string why;
  const cv::Mat image = decode(bytes, &why, kMaxDecodedBytes);
  if (!image.empty()) return ::testing::AssertionFailure() << "decoded " << image.cols << " x " << image.rows;
  if (why.rfind(format + ":", 0) != 0 || why.find(words) == std::string::npos)
    return ::testing::AssertionFailure() << "reason \"" << why << "\" lacks \"" << format << ":\" or \"" << words
                                         << "\"";
  return ::testing::AssertionSuccess();
}

// Every prefix shorter than `needed` bytes (where the pixels end) is refused
// with a reason; longer ones, missing only what follows the pixels, decode to
// the whole file's image.
void ExpectCutsRefused(Decoder decode, const Bytes& bytes, std::size_t needed) {
  std::string why;
  const cv::Mat whole = decode(bytes, &why, kMaxDecodedBytes);
  ASSERT_FALSE(whole.empty()) << why;
  for (std::size_t size = 0; size < bytes.size(); ++size) {
    const Bytes cut(bytes.begin(), bytes.begin() + size);
    why.clear();
    const cv::Mat image = decode(cut, &why, kMaxDecodedBytes);
    if (size < needed) {
      EXPECT_TRUE(image.empty() && !why.empty()) << "cut to " << size << " of " << bytes.size() << " bytes";
    } else {
      EXPECT_TRUE(why.empty() && SameBits(image, whole)) << "cut to " << size << " of " << bytes.size() << " bytes";
    }
  }
}

// ---------------------------------------------------------------- Radiance HDR

constexpr std::string_view kHdrHeader = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n";

// Values over 2^-40 to 2^40, zeros, and a stretch of equal pixels that
// run-length encoding makes a run of.
cv::Mat HdrImage(int rows, int cols, int channels) {
  cv::Mat image(rows, cols, CV_32FC(channels));
  cv::RNG rng(static_cast<std::uint64_t>(rows) * 1000 + cols);
  for (int r = 0; r < rows; ++r) {
    float* values = image.ptr<float>(r);
    for (int i = 0; i < cols * channels; ++i)
      values[i] = rng.uniform(0, 20) == 0 ? 0.0f : std::exp2(static_cast<float>(rng.uniform(-40.0, 40.0)));
  }
  image.row(0).colRange(0, cols / 2).setTo(cv::Scalar::all(0.75));
  return image;
}

// The first scanline (after the blank line and the resolution line) starts
// with 2, 2: run-length encoded.
bool RunLengthEncoded(const Bytes& file) {
  const std::string text(file.begin(), file.end());
  const std::size_t scanline = text.find('\n', text.find("\n\n") + 2) + 1;
  return file.size() >= scanline + 2 && file[scanline] == 2 && file[scanline + 1] == 2;
}

TEST(RadianceHdr, DecodesOpenCvsRunLengthEncodedFilesAsOpenCv) {
  for (const cv::Size size : {cv::Size(37, 5), cv::Size(8, 3), cv::Size(300, 2), cv::Size(0x7fff, 1)}) {
    const Bytes file = Encoded(".hdr", HdrImage(size.height, size.width, 3));
    ASSERT_TRUE(RunLengthEncoded(file)) << size;
    EXPECT_TRUE(DecodesAsOpenCv(DecodeRadianceHdr, file)) << size;
  }
}

TEST(RadianceHdr, DecodesOpenCvsFlatFilesAsOpenCv) {
  // OpenCV 4.6 writes flat scanlines when its first parameter is 0 (its
  // HDR_NONE; IMWRITE_HDR_COMPRESSION came later), and at widths below 8
  // whatever the parameter.
  for (const cv::Size size : {cv::Size(37, 5), cv::Size(8, 3), cv::Size(7, 4), cv::Size(1, 3)}) {
    const Bytes file = Encoded(".hdr", HdrImage(size.height, size.width, 3), {0, 0});
    ASSERT_FALSE(RunLengthEncoded(file)) << size;
    EXPECT_TRUE(DecodesAsOpenCv(DecodeRadianceHdr, file)) << size;
  }
  EXPECT_FALSE(RunLengthEncoded(Encoded(".hdr", HdrImage(4, 7, 3))));
}

TEST(RadianceHdr, DecodesMantissaTimesTwoToTheExponentLessOneHundredThirtySix) {
  using namespace std::string_literals;
  // R, G, B, E: 128, 64, 32 at 2^(129 - 136); E = 0 is black whatever the mantissas.
  const Bytes file = ToBytes(std::string(kHdrHeader) + "-Y 1 +X 2\n" + "\x80\x40\x20\x81\x01\x02\x03\x00"s);
  std::string why;
  const cv::Mat image = DecodeRadianceHdr(file, &why, kMaxDecodedBytes);
  ASSERT_FALSE(image.empty()) << why;
  EXPECT_EQ(image.type(), CV_32FC3);
  EXPECT_EQ(image.at<cv::Vec3f>(0, 0), cv::Vec3f(0.25f, 0.5f, 1.0f));
  EXPECT_EQ(image.at<cv::Vec3f>(0, 1), cv::Vec3f(0, 0, 0));
  EXPECT_TRUE(DecodesAsOpenCv(DecodeRadianceHdr, file));
  // The exponent's extremes: 255 * 2^119 and 2^-135, a float denormal.
  EXPECT_TRUE(DecodesAsOpenCv(DecodeRadianceHdr,
                              ToBytes(std::string(kHdrHeader) + "-Y 1 +X 2\n" + "\xff\x01\x80\xff\x01\x02\x03\x01"s)));
}

TEST(RadianceHdr, TellsFlatAndEncodedScanlinesApartOneByOne) {
  using namespace std::string_literals;
  // A flat scanline, then an encoded one, each read as what it is, as
  // Radiance reads them (OpenCV reads every scanline after a flat one as flat).
  std::string file = std::string(kHdrHeader) + "-Y 2 +X 8\n";
  for (int x = 0; x < 8; ++x) file += "\x80\x40\x20\x81";  // 128, 64, 32 at 2^-7
  file += "\x02\x02\x00\x08\x88\x40\x88\x40\x88\x40\x88\x82"s;  // runs of 64, 64, 64 at 2^-6
  std::string why;
  const cv::Mat image = DecodeRadianceHdr(ToBytes(file), &why, kMaxDecodedBytes);
  cv::Mat expected(2, 8, CV_32FC3, cv::Scalar(1.0f, 1.0f, 1.0f));
  expected.row(0).setTo(cv::Scalar(0.25f, 0.5f, 1.0f));
  EXPECT_TRUE(SameBits(image, expected)) << why;
}

TEST(RadianceHdr, ReadsHeaderVariantsAsOpenCv) {
  using namespace std::string_literals;
  const std::string pixels = "\x80\x40\x20\x81\x01\x02\x03\x00"s;
  for (const std::string& header : {"#?RGBE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n"s,
                                    "#?RADIANCE\nEXPOSURE=2\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n"s,
                                    "#?RADIANCE\nGAMMA=2.2\nPRIMARIES=0.64 0.33 0.3 0.6 0.15 0.06 0.3127 0.329\n"
                                    "FORMAT=32-bit_rle_rgbe\nEXPOSURE=0.5\nSOFTWARE=ra_xyze\n\n-Y 1 +X 2\n"s,
                                    "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y  1  +X  2\n"s})
    EXPECT_TRUE(DecodesAsOpenCv(DecodeRadianceHdr, ToBytes(header + pixels))) << header;
  // FORMAT is optional in Radiance's files (RGBE by default); OpenCV insists on it.
  std::string why;
  const cv::Mat image = DecodeRadianceHdr(ToBytes("#?RADIANCE\nEXPOSURE=1\n\n-Y 1 +X 2\n" + pixels), &why, kMaxDecodedBytes);
  EXPECT_TRUE(SameBits(image, cv::imdecode(ToBytes(std::string(kHdrHeader) + "-Y 1 +X 2\n" + pixels),
                                           cv::IMREAD_UNCHANGED)))
      << why;
}

TEST(RadianceHdr, RefusesWhatItDoesNotRead) {
  using namespace std::string_literals;
  const std::string pixels = "\x80\x40\x20\x81\x01\x02\x03\x00"s;
  const auto refused = [&](const std::string& file, const std::string& words) {
    return Refused(DecodeRadianceHdr, ToBytes(file), "Radiance HDR", words);
  };
  EXPECT_TRUE(refused("#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 2\n" + pixels, "32-bit_rle_xyze"));
  EXPECT_TRUE(refused("#?RADIANCE\nFORMAT=8-bit_grey\n\n-Y 1 +X 2\n" + pixels, "8-bit_grey"));
  EXPECT_TRUE(refused("#?AUTOPANO\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n" + pixels, "#?RADIANCE"));
  for (const std::string resolution : {"+Y 1 +X 2", "-Y 1 -X 2", "+X 2 -Y 1", "-Y 0 +X 2", "-Y 1 +X -2",
                                       "-Y 1 +X 2 +Z 3", "-Y 1 +X", "-Y 99999999999 +X 2", "-Y 1 +X 2x"})
    EXPECT_TRUE(refused(std::string(kHdrHeader) + resolution + "\n" + pixels, "\"" + resolution + "\""));
  // A run-length encoded scanline of another width, a run past its end and a count of 0.
  const std::string literal8 = "\x08\x01\x02\x03\x04\x05\x06\x07\x08"s;
  EXPECT_TRUE(refused(std::string(kHdrHeader) + "-Y 1 +X 8\n" + "\x02\x02\x00\x09"s + "\x88\x80"s + literal8 +
                          "\x88\x10\x88\x81"s,
                      "9 pixels wide"));
  EXPECT_TRUE(refused(std::string(kHdrHeader) + "-Y 1 +X 8\n" + "\x02\x02\x00\x08"s + "\x89\x80"s + literal8 +
                          "\x88\x10\x88\x81"s,
                      "bad run-length code"));
  EXPECT_TRUE(refused(std::string(kHdrHeader) + "-Y 1 +X 8\n" + "\x02\x02\x00\x08"s + "\x00\x88\x80"s + literal8 +
                          "\x88\x10\x88\x81"s,
                      "bad run-length code"));
}

TEST(RadianceHdr, RefusesHugeDimensionsBeforeAllocating) {
  EXPECT_TRUE(Refused(DecodeRadianceHdr, ToBytes(std::string(kHdrHeader) + "-Y 100000 +X 100000\n"), "Radiance HDR",
                      "100000 x 100000 pixels, past the 1 GiB limit"));
  // 12 bytes a pixel: 9460^2 of them are past 2^30 bytes, 9459^2 not.
  EXPECT_TRUE(Refused(DecodeRadianceHdr, ToBytes(std::string(kHdrHeader) + "-Y 9460 +X 9460\n"), "Radiance HDR",
                      "1 GiB"));
  EXPECT_TRUE(Refused(DecodeRadianceHdr, ToBytes(std::string(kHdrHeader) + "-Y 9459 +X 9459\n"), "Radiance HDR",
                      "truncated"));
  // Within the limit, but far more pixels than the bytes could hold.
  EXPECT_TRUE(Refused(DecodeRadianceHdr, ToBytes(std::string(kHdrHeader) + "-Y 9000 +X 9000\n\x02\x02\x23\x28"),
                      "Radiance HDR", "truncated"));
}

TEST(RadianceHdr, RefusesTruncatedFiles) {
  for (const std::vector<int>& parameters : {std::vector<int>{}, std::vector<int>{0, 0}}) {
    const Bytes file = Encoded(".hdr", HdrImage(3, 20, 3), parameters);
    ExpectCutsRefused(DecodeRadianceHdr, file, file.size());
  }
}

// Within RGBE's precision: each component within 1/128 of the pixel's largest
// (every mantissa truncated to 8 bits of the largest's exponent).
::testing::AssertionResult WithinRgbePrecision(const cv::Mat& decoded, const cv::Mat& written) {
  for (int r = 0; r < written.rows; ++r)
    for (int c = 0; c < written.cols; ++c) {
      const int channels = written.channels();
      const float* in = written.ptr<float>(r) + c * channels;
      const cv::Vec3f out = decoded.at<cv::Vec3f>(r, c);
      const float largest = *std::max_element(in, in + channels);
      for (int k = 0; k < 3; ++k) {
        const float expected = in[channels == 3 ? k : 0];
        if (!(std::abs(out[k] - expected) < largest / 128) && !(largest == 0 && out[k] == 0))
          return ::testing::AssertionFailure() << "(" << r << ", " << c << ") channel " << k << ": " << out[k]
                                               << " for " << expected;
      }
    }
  return ::testing::AssertionSuccess();
}

TEST(RadianceHdr, EncodedFilesReadAlikeInOpenCvAndHoldTheImage) {
  // Run-length encoded from 8 to 0x7fff pixels wide, flat otherwise.
  for (const cv::Size size : {cv::Size(40, 6), cv::Size(8, 2), cv::Size(0x7fff, 2), cv::Size(7, 5),
                              cv::Size(0x8000, 1)}) {
    for (const int channels : {3, 1}) {
      const cv::Mat image = HdrImage(size.height, size.width, channels);
      Bytes file;
      std::string why;
      ASSERT_TRUE(EncodeRadianceHdr(image, &file, &why)) << why;
      EXPECT_TRUE(why.empty());
      const bool encoded = size.width >= 8 && size.width <= 0x7fff;
      EXPECT_EQ(RunLengthEncoded(file), encoded) << size;
      if (!encoded) {
        EXPECT_EQ(file.size(), kHdrHeader.size() + std::to_string(size.height).size() +
                                   std::to_string(size.width).size() + 8 + 4 * size.area());
      }
      const cv::Mat decoded = DecodeRadianceHdr(file, &why, kMaxDecodedBytes);
      ASSERT_FALSE(decoded.empty()) << why;
      EXPECT_TRUE(DecodesAsOpenCv(DecodeRadianceHdr, file)) << size << " " << channels;
      EXPECT_TRUE(WithinRgbePrecision(decoded, image)) << size << " " << channels;
    }
  }
}

TEST(RadianceHdr, EncodingCompressesRunsAndKeepsRepresentableValuesExactly) {
  // 200 and 3 at 2^-7: mantissas RGBE holds as they are.
  cv::Mat image(4, 64, CV_32FC3, cv::Scalar(0.0f, 3.0f / 128, 200.0f / 128));
  image.at<cv::Vec3f>(2, 5) = cv::Vec3f(1.0f, 0.5f, 0.25f);
  Bytes file;
  std::string why;
  ASSERT_TRUE(EncodeRadianceHdr(image, &file, &why)) << why;
  const std::size_t flat_size = kHdrHeader.size() + std::string("-Y 4 +X 64\n").size() + 4 * 4 * 64;
  EXPECT_LT(file.size(), flat_size / 4);
  EXPECT_TRUE(SameBits(DecodeRadianceHdr(file, &why, kMaxDecodedBytes), image));
  EXPECT_TRUE(SameBits(cv::imdecode(file, cv::IMREAD_UNCHANGED), image));
  // A region of a larger image (rows apart in memory) as the same pixels copied.
  const cv::Mat larger = HdrImage(10, 50, 3);
  Bytes from_region, from_copy;
  ASSERT_TRUE(EncodeRadianceHdr(larger(cv::Rect(3, 2, 30, 5)), &from_region, &why));
  ASSERT_TRUE(EncodeRadianceHdr(larger(cv::Rect(3, 2, 30, 5)).clone(), &from_copy, &why));
  EXPECT_EQ(from_region, from_copy);
}

TEST(RadianceHdr, EncodingMakesWhatRgbeCannotHoldItsNearest) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), infinity = std::numeric_limits<float>::infinity();
  const float largest = std::ldexp(255.0f, 119);
  cv::Mat image(1, 5, CV_32FC3);
  // Negative and NaN: 0. Past the largest: the largest. Below 2^-128: black.
  image.at<cv::Vec3f>(0, 0) = cv::Vec3f(-1.0f, nan, 1.0f);
  image.at<cv::Vec3f>(0, 1) = cv::Vec3f(infinity, std::numeric_limits<float>::max(), 0.0f);
  image.at<cv::Vec3f>(0, 2) = cv::Vec3f(1e-39f, 0.0f, 0.0f);
  image.at<cv::Vec3f>(0, 3) = cv::Vec3f(-infinity, nan, -0.0f);
  image.at<cv::Vec3f>(0, 4) = cv::Vec3f(0.0f, 0.0f, 0.0f);
  Bytes file;
  std::string why;
  ASSERT_TRUE(EncodeRadianceHdr(image, &file, &why)) << why;
  const cv::Mat decoded = DecodeRadianceHdr(file, &why, kMaxDecodedBytes);
  ASSERT_FALSE(decoded.empty()) << why;
  EXPECT_EQ(decoded.at<cv::Vec3f>(0, 0), cv::Vec3f(0.0f, 0.0f, 1.0f));
  EXPECT_EQ(decoded.at<cv::Vec3f>(0, 1), cv::Vec3f(largest, largest, 0.0f));
  for (int c = 2; c < 5; ++c) EXPECT_EQ(decoded.at<cv::Vec3f>(0, c), cv::Vec3f(0.0f, 0.0f, 0.0f)) << c;
  EXPECT_TRUE(DecodesAsOpenCv(DecodeRadianceHdr, file));
}

TEST(RadianceHdr, EncodingRefusesOtherTypes) {
  for (const int type : {CV_8UC3, CV_16UC3, CV_64FC3, CV_32FC2, CV_32FC4}) {
    Bytes file;
    std::string why;
    EXPECT_FALSE(EncodeRadianceHdr(cv::Mat(2, 2, type, cv::Scalar::all(1)), &file, &why)) << type;
    EXPECT_NE(why.find("Radiance HDR"), std::string::npos) << why;
    EXPECT_TRUE(file.empty());
  }
  Bytes file;
  std::string why;
  EXPECT_FALSE(EncodeRadianceHdr(cv::Mat(0, 0, CV_32FC3), &file, &why));
  EXPECT_FALSE(why.empty());
}

// ------------------------------------------------------------------------ PNM

cv::Mat IntegerImage(int rows, int cols, int type) {
  cv::Mat image(rows, cols, type);
  cv::RNG rng(static_cast<std::uint64_t>(rows) * 100 + cols + type);
  rng.fill(image, cv::RNG::UNIFORM, 0, CV_MAT_DEPTH(type) == CV_8U ? 256 : 65536);
  return image;
}

TEST(Pnm, DecodesOpenCvsFilesAsOpenCv) {
  struct Case {
    const char* extension;
    int type;
    const char* plain_magic;
    const char* binary_magic;
  };
  for (const Case& c : {Case{".pgm", CV_8UC1, "P2", "P5"}, Case{".pgm", CV_16UC1, "P2", "P5"},
                        Case{".ppm", CV_8UC3, "P3", "P6"}, Case{".ppm", CV_16UC3, "P3", "P6"},
                        Case{".pbm", CV_8UC1, "P1", "P4"}}) {
    for (const int binary : {0, 1}) {
      for (const cv::Size size : {cv::Size(13, 7), cv::Size(1, 1), cv::Size(16, 2)}) {
        const Bytes file = Encoded(c.extension, IntegerImage(size.height, size.width, c.type),
                                   {cv::IMWRITE_PXM_BINARY, binary});
        ASSERT_EQ(std::string(file.begin(), file.begin() + 2), binary ? c.binary_magic : c.plain_magic);
        EXPECT_TRUE(DecodesAsOpenCv(DecodePnm, file)) << c.extension << " " << c.type << " binary " << binary;
      }
    }
  }
}

cv::Mat DecodedPnm(const std::string& text) {
  std::string why;
  cv::Mat image = DecodePnm(ToBytes(text), &why, kMaxDecodedBytes);
  EXPECT_FALSE(image.empty()) << why;
  return image;
}

TEST(Pnm, ScalesPlainEightBitSamplesToTheirMaxvalAsOpenCv) {
  // v * 255 / maxval, truncated; past maxval, maxval.
  const std::string seven = "P2\n6 1\n7\n1 3 4 6 7 9\n";
  EXPECT_TRUE(SameBits(DecodedPnm(seven), cv::Mat_<std::uint8_t>({1, 6}, {36, 109, 145, 218, 255, 255})));
  EXPECT_TRUE(DecodesAsOpenCv(DecodePnm, ToBytes(seven)));
  EXPECT_TRUE(DecodesAsOpenCv(DecodePnm, ToBytes("P3\n2 1\n100\n10 50 99 100 0 300\n")));
  EXPECT_TRUE(DecodesAsOpenCv(DecodePnm, ToBytes("P2\n3 1\n1\n0 1 1\n")));
  const std::string full = "P2\n3 1\n255\n0 128 255\n";
  EXPECT_TRUE(SameBits(DecodedPnm(full), cv::Mat_<std::uint8_t>({1, 3}, {0, 128, 255})));
  EXPECT_TRUE(DecodesAsOpenCv(DecodePnm, ToBytes(full)));
}

TEST(Pnm, KeepsBinaryAndSixteenBitSamplesAsStoredAsOpenCv) {
  using namespace std::string_literals;
  // Binary samples are neither scaled nor clamped; plain 16-bit ones only clamped.
  const std::string binary8 = "P5\n3 1\n100\n\x00\x32\xc8"s;
  EXPECT_TRUE(SameBits(DecodedPnm(binary8), cv::Mat_<std::uint8_t>({1, 3}, {0, 50, 200})));
  const std::string plain16 = "P2\n4 1\n1000\n0 500 1000 2000\n";
  EXPECT_TRUE(SameBits(DecodedPnm(plain16), cv::Mat_<std::uint16_t>({1, 4}, {0, 500, 1000, 1000})));
  const std::string binary16 = "P5\n2 1\n1000\n\xff\xff\x01\xf4"s;
  EXPECT_TRUE(SameBits(DecodedPnm(binary16), cv::Mat_<std::uint16_t>({1, 2}, {65535, 500})));
  const std::string colour16 = "P6\n1 1\n256\n\x01\x02\x03\x04\x05\x06"s;
  EXPECT_EQ(DecodedPnm(colour16).at<cv::Vec3w>(0, 0), cv::Vec3w(0x0506, 0x0304, 0x0102));
  for (const std::string& file : {binary8, plain16, binary16, colour16, "P3\n1 1\n1000\n10 50 2000\n"s})
    EXPECT_TRUE(DecodesAsOpenCv(DecodePnm, ToBytes(file))) << file;
}

TEST(Pnm, ReadsCommentsSpacingAndBitmapsAsOpenCv) {
  using namespace std::string_literals;
  for (const std::string& file :
       {"P2 # greys\n# more\n2 # width\n1\n#maxval next\n255\n1 # a sample\n2\n"s, "P2\r2 1\r255\r1 2\r"s,
        "P2\t2\v1\f255 1\n\n 2 "s, "P1\n2 1#\n01"s, "P1\n4 2\n0101\n1100\n"s, "P1\n4 1\n01#x\n01\n"s,
        "P1 3 2 1 0 0 0 1 1"s, "P5\n# binary\n2 1 255\t\x01\x02"s, "P4\n10 2\n\xa5\xc0\x5a\x40"s,
        "P4 8 1 \xff"s, "P2\n2 1\n0255\n0001 2\n"s, "P5\n1 1\n255\n\x07 trailing bytes"s})
    EXPECT_TRUE(DecodesAsOpenCv(DecodePnm, ToBytes(file))) << file;
  // Bitmaps: 0 is white (255), 1 black (0); P4 rows start at a byte.
  EXPECT_TRUE(SameBits(DecodedPnm("P4\n10 2\n\xa5\xc0\x5a\x40"s),
                       cv::Mat_<std::uint8_t>({2, 10}, {0, 255, 0, 255, 255, 0, 255, 0, 0, 0,  //
                                                        255, 0, 255, 0, 0, 255, 0, 255, 255, 0})));
  EXPECT_TRUE(SameBits(DecodedPnm("P1 3 1 1 0 1"), cv::Mat_<std::uint8_t>({1, 3}, {0, 255, 0})));
  // Colour is B, G, R in memory.
  EXPECT_EQ(DecodedPnm("P3 1 1 255 1 2 3\n").at<cv::Vec3b>(0, 0), cv::Vec3b(3, 2, 1));
  // A # right after a number starts a comment, as in Netpbm (OpenCV reads on
  // inside the comment: 7, 1).
  EXPECT_TRUE(SameBits(DecodedPnm("P2\n2 1\n255\n7#1 comment\n9\n"), cv::Mat_<std::uint8_t>({1, 2}, {7, 9})));
}

TEST(Pnm, RefusesWhatItDoesNotRead) {
  using namespace std::string_literals;
  const auto refused = [](const std::string& file, const std::string& words) {
    return Refused(DecodePnm, ToBytes(file), "PNM", words);
  };
  EXPECT_TRUE(refused("P7\nWIDTH 1\n", "P7 (PAM or PFM) is not supported"));
  EXPECT_TRUE(refused("Pf\n1 1\n-1\n", "Pf (PAM or PFM)"));
  EXPECT_TRUE(refused("PF\n1 1\n-1\n", "PF (PAM or PFM)"));
  EXPECT_TRUE(refused("P8\n1 1\n255\n", "no P1-P6"));
  EXPECT_TRUE(refused("BM", "no P1-P6"));
  EXPECT_TRUE(refused("P31 1 255 1 2 3\n", "no white space after the magic number P3"));
  EXPECT_TRUE(refused("P5", "no white space after the magic number P5"));
  EXPECT_TRUE(refused("P2\n0 1\n255\n", "0 x 1 pixels"));
  EXPECT_TRUE(refused("P2\n1 1\n0\n0\n", "maxval 0"));
  EXPECT_TRUE(refused("P2\n1 1\n65536\n0\n", "maxval 65536"));
  EXPECT_TRUE(refused("P2\n1 1\n255\n99999999999\n", "a number past 2147483647"));
  EXPECT_TRUE(refused("P2\n2 1\n255\n1,2\n", "',' after a number"));
  EXPECT_TRUE(refused("P3\n1 1\n255\n-1 2 3\n", "'-' where a number should be"));
  EXPECT_TRUE(refused("P2\n1 1\n255\nx\n", "'x' where a number should be"));
  EXPECT_TRUE(refused("P1\n2 1\n0 2\n", "'2' where a bitmap's 0 or 1 should be"));
  EXPECT_TRUE(refused("P5\n2 1\n255#x\n\x01\x02"s, "white-space byte before the pixels"));
  EXPECT_TRUE(refused("P4\n8 1\xff"s, "after a number"));
}

TEST(Pnm, RefusesHugeDimensionsBeforeAllocating) {
  EXPECT_TRUE(Refused(DecodePnm, ToBytes("P5\n70000 70000\n255\n"), "PNM",
                      "header says 70000 x 70000 pixels, past the 1 GiB limit"));
  EXPECT_TRUE(Refused(DecodePnm, ToBytes("P6 20000 10000 65535\n"), "PNM", "past the 1 GiB limit"));
  // 2^30 samples of a byte are the most.
  EXPECT_TRUE(Refused(DecodePnm, ToBytes("P5 32768 32769 255\n"), "PNM", "1 GiB"));
  EXPECT_TRUE(Refused(DecodePnm, ToBytes("P5 32768 32768 255\n"), "PNM", "truncated"));
  EXPECT_TRUE(Refused(DecodePnm, ToBytes("P5 16384 32769 65535\n"), "PNM", "1 GiB"));
  // Within the limit, but far more samples than the bytes could hold.
  EXPECT_TRUE(Refused(DecodePnm, ToBytes("P2 30000 30000 255\n1 2 3\n"), "PNM", "truncated"));
  EXPECT_TRUE(Refused(DecodePnm, ToBytes("P1 30000 30000\n0101"), "PNM", "truncated"));
}

TEST(Pnm, RefusesTruncatedFiles) {
  for (const int binary : {0, 1}) {
    for (const auto& [extension, type] : {std::pair{".pgm", CV_16UC1}, std::pair{".ppm", CV_8UC3},
                                          std::pair{".ppm", CV_16UC3}, std::pair{".pbm", CV_8UC1}}) {
      const Bytes file = Encoded(extension, IntegerImage(3, 11, type), {cv::IMWRITE_PXM_BINARY, binary});
      // Plain samples end at their last digit and, but for a bitmap's, the
      // white space after it; what follows may go.
      const std::size_t last_digit = std::string(file.begin(), file.end()).find_last_of("0123456789");
      const bool bitmap = std::string(extension) == ".pbm";
      ExpectCutsRefused(DecodePnm, file, binary ? file.size() : last_digit + (bitmap ? 1 : 2));
    }
  }
}

// ------------------------------------------------------------------------ BMP

struct BmpFile {
  std::uint32_t header_bytes = 40;  // 12: OS/2's core header
  std::int32_t width = 0, height = 0;
  int bits = 24;
  std::uint32_t compression = 0;
  std::vector<std::uint32_t> masks{};    // R, G, B(, A): in the header from 52 bytes on, right after a 40-byte one
  std::vector<std::uint32_t> palette{};  // 0xRRGGBB
  std::optional<std::uint32_t> colours_used{};
  Bytes pixels{};  // padded rows or RLE codes, as stored
};

void PutLe(Bytes* out, std::uint32_t value, int bytes) {
  for (int i = 0; i < bytes; ++i) out->push_back(static_cast<std::uint8_t>(value >> (8 * i)));
}

Bytes Built(const BmpFile& spec) {
  Bytes info;
  PutLe(&info, spec.header_bytes, 4);
  if (spec.header_bytes == 12) {
    PutLe(&info, static_cast<std::uint32_t>(spec.width), 2);
    PutLe(&info, static_cast<std::uint32_t>(spec.height), 2);
    PutLe(&info, 1, 2);
    PutLe(&info, spec.bits, 2);
  } else {
    PutLe(&info, static_cast<std::uint32_t>(spec.width), 4);
    PutLe(&info, static_cast<std::uint32_t>(spec.height), 4);
    PutLe(&info, 1, 2);
    PutLe(&info, spec.bits, 2);
    PutLe(&info, spec.compression, 4);
    PutLe(&info, static_cast<std::uint32_t>(spec.pixels.size()), 4);
    PutLe(&info, 2835, 4);  // 72 dpi
    PutLe(&info, 2835, 4);
    PutLe(&info, spec.colours_used.value_or(spec.bits <= 8 ? spec.palette.size() : 0), 4);
    PutLe(&info, 0, 4);
    if (spec.header_bytes >= 52)
      for (std::size_t i = 0; i < 4 && i < spec.masks.size(); ++i) PutLe(&info, spec.masks[i], 4);
    info.resize(spec.header_bytes);
  }
  if (spec.header_bytes == 40)
    for (const std::uint32_t mask : spec.masks) PutLe(&info, mask, 4);
  for (const std::uint32_t colour : spec.palette) PutLe(&info, colour, spec.header_bytes == 12 ? 3 : 4);
  const auto offset = static_cast<std::uint32_t>(14 + info.size());
  Bytes file = {'B', 'M'};
  PutLe(&file, offset + static_cast<std::uint32_t>(spec.pixels.size()), 4);
  PutLe(&file, 0, 4);
  PutLe(&file, offset, 4);
  file.insert(file.end(), info.begin(), info.end());
  file.insert(file.end(), spec.pixels.begin(), spec.pixels.end());
  return file;
}

cv::Mat DecodedBmp(const Bytes& file) {
  std::string why;
  cv::Mat image = DecodeBmp(file, &why, kMaxDecodedBytes);
  EXPECT_FALSE(image.empty()) << why;
  return image;
}

TEST(Bmp, DecodesOpenCvsFilesAsOpenCv) {
  // Grey as 8 bits with a grey palette, colour as 24 bits, B, G, R, A as 32
  // bits (which OpenCV reads back as 3 channels); every row padding.
  for (const auto& [type, bits] : {std::pair{CV_8UC1, 8}, std::pair{CV_8UC3, 24}, std::pair{CV_8UC4, 32}}) {
    for (int width = 1; width <= 8; ++width) {
      const Bytes file = Encoded(".bmp", IntegerImage(3, width, type));
      ASSERT_EQ(file[28], bits);
      EXPECT_TRUE(DecodesAsOpenCv(DecodeBmp, file)) << bits << " bits, " << width << " wide";
    }
  }
}

const Bytes kPixels32 = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16};  // 2 x 2, B, G, R, A

TEST(Bmp, ReadsThirtyTwoBitsAsOpenCv) {
  constexpr std::uint32_t kRgb = 0, kBitFields = 3;
  const std::vector<std::uint32_t> bgra = {0xff0000, 0xff00, 0xff, 0xff000000}, bgr = {0xff0000, 0xff00, 0xff, 0};
  for (const std::int32_t height : {2, -2}) {
    // Without bit fields the fourth byte is dropped; with them it is alpha,
    // or 255 where the header's A mask is 0.
    const Bytes plain = Built({.width = 2, .height = height, .bits = 32, .compression = kRgb, .pixels = kPixels32});
    const Bytes fields_after = Built({.width = 2, .height = height, .bits = 32, .compression = kBitFields,
                                      .masks = {0xff0000, 0xff00, 0xff}, .pixels = kPixels32});
    const Bytes v2 = Built({.header_bytes = 52, .width = 2, .height = height, .bits = 32,
                            .compression = kBitFields, .masks = bgr, .pixels = kPixels32});  // no A mask
    const Bytes v4 = Built({.header_bytes = 108, .width = 2, .height = height, .bits = 32,
                            .compression = kBitFields, .masks = bgra, .pixels = kPixels32});
    const Bytes v5_opaque = Built({.header_bytes = 124, .width = 2, .height = height, .bits = 32,
                                   .compression = kBitFields, .masks = bgr, .pixels = kPixels32});
    const Bytes v5_plain = Built({.header_bytes = 124, .width = 2, .height = height, .bits = 32,
                                  .compression = kRgb, .masks = bgra, .pixels = kPixels32});
    for (const Bytes& file : {plain, fields_after, v2, v4, v5_opaque, v5_plain})
      EXPECT_TRUE(DecodesAsOpenCv(DecodeBmp, file)) << height;
    const int top = height < 0 ? 0 : 1;  // the image row of the first row stored
    EXPECT_EQ(DecodedBmp(plain).at<cv::Vec3b>(top, 1), cv::Vec3b(5, 6, 7));
    EXPECT_EQ(DecodedBmp(v4).at<cv::Vec4b>(top, 1), cv::Vec4b(5, 6, 7, 8));
    EXPECT_EQ(DecodedBmp(v5_opaque).at<cv::Vec4b>(1 - top, 0), cv::Vec4b(9, 10, 11, 255));
  }
}

TEST(Bmp, ReadsPalettesAsOpenCv) {
  const std::vector<std::uint32_t> colours = {0x000000, 0x102030, 0xffffff, 0x808080};
  const std::vector<std::uint32_t> greys = {0x000000, 0x101010, 0xffffff, 0x808080};
  const Bytes indices8 = {0, 1, 2, 0, 3, 1, 0, 0};  // 3 x 2, rows padded to 4 bytes
  const Bytes beyond8 = {0, 1, 2, 0, 3, 200, 1, 0};  // indices past the palette are black
  const Bytes indices4 = {0x01, 0x20, 0, 0, 0x31, 0x30, 0, 0};
  const Bytes bits1 = {0xa5, 0xc0, 0, 0, 0x5a, 0x40, 0, 0};  // 10 x 2
  const std::vector<BmpFile> files = {
      {.width = 3, .height = 2, .bits = 8, .palette = colours, .pixels = indices8},
      {.width = 3, .height = -2, .bits = 8, .palette = greys, .pixels = indices8},
      {.width = 3, .height = 2, .bits = 8, .palette = {0x000000, 0x101010, 0xffffff}, .pixels = beyond8},
      {.width = 3, .height = 2, .bits = 8, .palette = {0x000000, 0x102030, 0xffffff}, .pixels = beyond8},
      {.width = 3, .height = 2, .bits = 8, .palette = std::vector<std::uint32_t>(256, 0x050505), .colours_used = 0,
       .pixels = indices8},
      {.header_bytes = 124, .width = 3, .height = 2, .bits = 8, .palette = greys, .pixels = indices8},
      {.width = 3, .height = 2, .bits = 4, .palette = colours, .pixels = indices4},
      {.width = 3, .height = 2, .bits = 4, .palette = greys, .pixels = indices4},
      {.width = 10, .height = 2, .bits = 1, .palette = {0x000000, 0xffffff}, .pixels = bits1},
      {.width = 10, .height = -2, .bits = 1, .palette = {0x0000ff, 0x00ff00}, .pixels = bits1},
  };
  for (std::size_t i = 0; i < files.size(); ++i) EXPECT_TRUE(DecodesAsOpenCv(DecodeBmp, Built(files[i]))) << i;
  EXPECT_EQ(DecodedBmp(Built(files[0])).type(), CV_8UC3);
  EXPECT_EQ(DecodedBmp(Built(files[0])).at<cv::Vec3b>(1, 1), cv::Vec3b(0x30, 0x20, 0x10));
  EXPECT_TRUE(SameBits(DecodedBmp(Built(files[1])), cv::Mat_<std::uint8_t>({2, 3}, {0, 0x10, 0xff, 0x80, 0x10, 0})));
  EXPECT_TRUE(SameBits(DecodedBmp(Built(files[2])), cv::Mat_<std::uint8_t>({2, 3}, {0, 0, 0x10, 0, 0x10, 0xff})));
}

TEST(Bmp, ReadsSixteenBitsAsOpenCv) {
  constexpr std::uint32_t kBitFields = 3;
  const Bytes pixels = {0xff, 0x7f, 0x21, 0x84, 0x1f, 0x00, 0xe0, 0x03};  // 2 x 2
  const BmpFile rgb555 = {.width = 2, .height = 2, .bits = 16, .pixels = pixels};
  const BmpFile fields565 = {.width = 2, .height = -2, .bits = 16, .compression = kBitFields,
                             .masks = {0xf800, 0x7e0, 0x1f}, .pixels = pixels};
  const BmpFile fields555 = {.width = 2, .height = 2, .bits = 16, .compression = kBitFields,
                             .masks = {0x7c00, 0x3e0, 0x1f}, .pixels = pixels};
  for (const BmpFile& file : {rgb555, fields565, fields555}) EXPECT_TRUE(DecodesAsOpenCv(DecodeBmp, Built(file)));
  // Each field at the top of its byte, the low bits 0.
  EXPECT_EQ(DecodedBmp(Built(rgb555)).at<cv::Vec3b>(1, 0), cv::Vec3b(248, 248, 248));
  EXPECT_EQ(DecodedBmp(Built(fields565)).at<cv::Vec3b>(0, 0), cv::Vec3b(248, 252, 120));
  // OpenCV looks for the masks after a V4 or V5 header rather than in it, and
  // refuses; here they are read where the header holds them.
  BmpFile v5 = fields565;
  v5.header_bytes = 124;
  EXPECT_TRUE(SameBits(DecodedBmp(Built(v5)), DecodedBmp(Built(fields565))));
}

TEST(Bmp, ReadsRunLengthCodesAsOpenCv) {
  constexpr std::uint32_t kRle8 = 1, kRle4 = 2;
  const std::vector<std::uint32_t> colours = {0x0a0b0c, 0x102030, 0xffffff, 0x808080};
  const std::vector<BmpFile> files = {
      // A run, end of line; 3 indices as stored, padded; end of line, end of bitmap.
      {.width = 3, .height = 2, .bits = 8, .compression = kRle8, .palette = colours,
       .pixels = {3, 1, 0, 0, 0, 3, 0, 2, 3, 0, 0, 0, 0, 1}},
      // The end of the bitmap early, a delta: the pixels skipped are index 0.
      {.width = 4, .height = 3, .bits = 8, .compression = kRle8, .palette = colours,
       .pixels = {2, 1, 0, 2, 1, 1, 1, 3, 0, 1}},
      {.width = 4, .height = 2, .bits = 8, .compression = kRle8, .palette = {0x404040, 0x101010},
       .pixels = {2, 1, 0, 1}},
      {.width = 2, .height = -2, .bits = 8, .compression = kRle8, .palette = colours,
       .pixels = {2, 1, 0, 0, 2, 2, 0, 1}},
      // Complete without the end-of-bitmap code.
      {.width = 2, .height = 2, .bits = 8, .compression = kRle8, .palette = colours, .pixels = {2, 1, 0, 0, 2, 2}},
      // RLE4: runs alternate the two indices of their byte; 5 indices as stored.
      {.width = 5, .height = 2, .bits = 4, .compression = kRle4, .palette = colours,
       .pixels = {5, 0x12, 0, 0, 0, 5, 0x12, 0x30, 0x20, 0, 0, 0, 0, 1}},
  };
  for (std::size_t i = 0; i < files.size(); ++i) EXPECT_TRUE(DecodesAsOpenCv(DecodeBmp, Built(files[i]))) << i;
  const cv::Mat skipped = DecodedBmp(Built(files[1]));
  EXPECT_EQ(skipped.at<cv::Vec3b>(2, 0), cv::Vec3b(0x30, 0x20, 0x10));
  EXPECT_EQ(skipped.at<cv::Vec3b>(1, 3), cv::Vec3b(0x80, 0x80, 0x80));
  EXPECT_EQ(skipped.at<cv::Vec3b>(0, 0), cv::Vec3b(0x0c, 0x0b, 0x0a));
  // An RLE4 delta moves as an RLE8 one does (OpenCV 4.6 drops its rows and
  // reads codes past it).
  const cv::Mat moved = DecodedBmp(Built({.width = 4, .height = 3, .bits = 4, .compression = kRle4,
                                          .palette = colours, .pixels = {2, 0x11, 0, 2, 1, 1, 1, 0x30, 0, 1}}));
  EXPECT_TRUE(SameBits(moved, skipped));
}

TEST(Bmp, ReadsOs2CoreHeaders) {
  // OpenCV 4.6 misreads these (the 24-bit one as grey, the 3-byte palette as 4-byte entries).
  const cv::Mat rgb = DecodedBmp(Built({.header_bytes = 12, .width = 2, .height = 2, .bits = 24,
                                        .pixels = {1, 2, 3, 4, 5, 6, 0, 0, 7, 8, 9, 10, 11, 12, 0, 0}}));
  EXPECT_TRUE(SameBits(rgb, cv::Mat_<cv::Vec3b>({2, 2}, {{7, 8, 9}, {10, 11, 12}, {1, 2, 3}, {4, 5, 6}})));
  const cv::Mat indexed = DecodedBmp(Built({.header_bytes = 12, .width = 3, .height = 1, .bits = 4,
                                            .palette = std::vector<std::uint32_t>(16, 0x102030),
                                            .pixels = {0x01, 0x20, 0, 0}}));
  ASSERT_EQ(indexed.type(), CV_8UC3);
  EXPECT_EQ(indexed.at<cv::Vec3b>(0, 2), cv::Vec3b(0x30, 0x20, 0x10));
}

TEST(Bmp, RefusesWhatItDoesNotRead) {
  constexpr std::uint32_t kRle8 = 1, kRle4 = 2, kBitFields = 3;
  const Bytes pixels24 = {1, 2, 3, 4, 5, 6, 0, 0, 7, 8, 9, 10, 11, 12, 0, 0};
  const std::vector<std::uint32_t> colours = {0x000000, 0x102030, 0xffffff, 0x808080};
  const auto refused = [](const BmpFile& file, const std::string& words) {
    return Refused(DecodeBmp, Built(file), "BMP", words);
  };
  EXPECT_TRUE(refused({.width = 2, .height = 2, .compression = 4, .pixels = pixels24}, "BI_JPEG compression"));
  EXPECT_TRUE(refused({.width = 2, .height = 2, .compression = 5, .pixels = pixels24}, "BI_PNG compression"));
  EXPECT_TRUE(refused({.width = 2, .height = 2, .bits = 32, .compression = 6, .pixels = kPixels32},
                      "BI_ALPHABITFIELDS compression"));
  EXPECT_TRUE(refused({.width = 4, .height = 1, .bits = 2, .palette = colours, .pixels = {0x1b, 0, 0, 0}},
                      "2 bits a pixel with BI_RGB"));
  EXPECT_TRUE(refused({.width = 1, .height = 1, .bits = 48, .pixels = {1, 2, 3, 4, 5, 6, 0, 0}}, "48 bits"));
  EXPECT_TRUE(refused({.width = 4, .height = 1, .compression = kRle8, .pixels = {4, 0, 0, 1}}, "24 bits a pixel"));
  EXPECT_TRUE(refused({.width = 4, .height = 1, .bits = 8, .compression = kRle4, .palette = colours,
                       .pixels = {4, 0, 0, 1}},
                      "8 bits a pixel with BI_RLE4"));
  EXPECT_TRUE(refused({.width = 2, .height = 2, .bits = 16, .compression = kBitFields, .masks = {0xf00, 0xf0, 0xf},
                       .pixels = pixels24},
                      "5-5-5 and 5-6-5"));
  EXPECT_TRUE(refused({.header_bytes = 124, .width = 2, .height = 2, .bits = 32, .compression = kBitFields,
                       .masks = {0xff, 0xff00, 0xff0000, 0xff000000}, .pixels = kPixels32},
                      "bytes B, G, R, A"));
  EXPECT_TRUE(refused({.header_bytes = 124, .width = 2, .height = 2, .bits = 32, .compression = kBitFields,
                       .masks = {0xff0000, 0xff00, 0xff, 0xff}, .pixels = kPixels32},
                      "bytes B, G, R, A"));
  EXPECT_TRUE(refused({.header_bytes = 16, .width = 2, .height = 2, .pixels = pixels24}, "16-byte info header"));
  EXPECT_TRUE(refused({.width = 0, .height = 2, .pixels = pixels24}, "0 x 2 pixels"));
  EXPECT_TRUE(refused({.width = 2, .height = 0, .pixels = pixels24}, "2 x 0 pixels"));
  EXPECT_TRUE(refused({.width = -2, .height = 2, .pixels = pixels24}, "-2 x 2 pixels"));
  // RLE codes past their row: a run, indices as stored, a delta.
  EXPECT_TRUE(refused({.width = 4, .height = 2, .bits = 8, .compression = kRle8, .palette = colours,
                       .pixels = {6, 1, 0, 0, 0, 1}},
                      "crosses the end of a row"));
  EXPECT_TRUE(refused({.width = 2, .height = 2, .bits = 8, .compression = kRle8, .palette = colours,
                       .pixels = {0, 3, 1, 2, 3, 0, 0, 1}},
                      "crosses the end of a row"));
  EXPECT_TRUE(refused({.width = 3, .height = 1, .bits = 4, .compression = kRle4, .palette = colours,
                       .pixels = {4, 0x12, 0, 1}},
                      "crosses the end of a row"));
  EXPECT_TRUE(refused({.width = 4, .height = 2, .bits = 8, .compression = kRle8, .palette = colours,
                       .pixels = {1, 1, 0, 2, 4, 0, 0, 1}},
                      "delta moves past"));
  EXPECT_TRUE(Refused(DecodeBmp, ToBytes("BA\x36\x10"), "BMP", "no BM signature"));
}

TEST(Bmp, RefusesHugeDimensionsBeforeAllocating) {
  EXPECT_TRUE(Refused(DecodeBmp, Built({.width = 70000, .height = 70000}), "BMP",
                      "header says 70000 x 70000 pixels, past the 1 GiB limit"));
  EXPECT_TRUE(Refused(DecodeBmp, Built({.width = 1, .height = std::numeric_limits<std::int32_t>::min()}), "BMP",
                      "pixels"));
  // 2^30 bytes of pixels are the most: a grey palette's one channel, a colour one's three.
  EXPECT_TRUE(Refused(DecodeBmp, Built({.width = 32768, .height = 32769, .bits = 8, .palette = {0x101010}}), "BMP",
                      "1 GiB"));
  EXPECT_TRUE(Refused(DecodeBmp, Built({.width = 32768, .height = 32768, .bits = 8, .palette = {0x101010}}), "BMP",
                      "truncated"));
  EXPECT_TRUE(Refused(DecodeBmp, Built({.width = 32768, .height = 16384, .bits = 8, .palette = {0x102030}}), "BMP",
                      "1 GiB"));
  EXPECT_TRUE(Refused(DecodeBmp, Built({.width = 20000, .height = -20000, .bits = 8, .palette = {0x101010}}),
                      "BMP", "truncated"));
}

TEST(Bmp, RefusesTruncatedFiles) {
  for (const int type : {CV_8UC1, CV_8UC3, CV_8UC4}) {
    const Bytes file = Encoded(".bmp", IntegerImage(3, 5, type));
    ExpectCutsRefused(DecodeBmp, file, file.size());
  }
  // Without its end-of-bitmap code an RLE file whose rows are complete still reads.
  const Bytes rle = Built({.width = 3, .height = 2, .bits = 8, .compression = 1, .palette = {0x000000, 0x102030},
                           .pixels = {3, 1, 0, 0, 0, 3, 0, 1, 1, 0, 0, 1}});
  ExpectCutsRefused(DecodeBmp, rle, rle.size() - 2);
}

}  // namespace
}  // namespace photorig::solvers::codecs::internal
