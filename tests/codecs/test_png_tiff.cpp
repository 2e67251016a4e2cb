// The project's PNG and TIFF codecs against OpenCV's: every file OpenCV
// writes decodes to the same pixels, every file the project writes decodes in
// OpenCV to the pixels written; variants OpenCV does not write (palettes,
// grey with alpha, 1-bit, tiles, separate planes) decode as OpenCV decodes
// the same bytes; truncated, corrupt and oversized files are refused with a
// reason. And the read modes, and the choice of encoding by extension.
#include "photorig/solvers/codecs/image_codecs.h"

#include "same_bits.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <tiffio.h>
#include <zlib.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <unistd.h>

namespace photorig::solvers::codecs {
namespace {

// 7 x 5, a 4-bit palette of six colours, three of them transparent or half so
const std::vector<std::uint8_t> kPalettePngWithTransparency = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00,
    0x00, 0x07, 0x00, 0x00, 0x00, 0x05, 0x04, 0x03, 0x00, 0x00, 0x00, 0x7b, 0xb4, 0xeb, 0xeb, 0x00, 0x00, 0x00,
    0x12, 0x50, 0x4c, 0x54, 0x45, 0xff, 0x00, 0x00, 0x00, 0xff, 0x00, 0x00, 0x00, 0xff, 0x0a, 0x14, 0x1e, 0xc8,
    0x64, 0x32, 0x01, 0x02, 0x03, 0x94, 0x70, 0x86, 0xeb, 0x00, 0x00, 0x00, 0x06, 0x74, 0x52, 0x4e, 0x53, 0xff,
    0x80, 0x00, 0xff, 0xff, 0xff, 0x3b, 0x3a, 0x3a, 0xdd, 0x00, 0x00, 0x00, 0x21, 0x49, 0x44, 0x41, 0x54, 0x78,
    0x9c, 0x63, 0x30, 0x0c, 0x35, 0x64, 0x60, 0x30, 0x56, 0x70, 0x71, 0x60, 0x70, 0x55, 0x65, 0x56, 0x60, 0x50,
    0x76, 0x64, 0x72, 0x60, 0x10, 0x16, 0x14, 0x64, 0x00, 0x00, 0x2b, 0xb4, 0x02, 0xf7, 0xdf, 0xd2, 0x22, 0x1b,
    0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82
};
// 6 x 4, 8-bit grey with alpha
const std::vector<std::uint8_t> kGreyAlphaPng = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00,
    0x00, 0x06, 0x00, 0x00, 0x00, 0x04, 0x08, 0x04, 0x00, 0x00, 0x00, 0x07, 0x0d, 0x86, 0xc8, 0x00, 0x00, 0x00,
    0x3f, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x01, 0x34, 0x00, 0xcb, 0xff, 0x00, 0x99, 0xb2, 0xd7, 0x4c, 0x34,
    0x27, 0xfa, 0x48, 0xd7, 0x32, 0xa1, 0xdf, 0x02, 0xd7, 0xfa, 0xca, 0x9d, 0xf2, 0xea, 0x5f, 0xb9, 0x06, 0xd4,
    0x51, 0xa0, 0x04, 0x1f, 0x5a, 0x9b, 0xcc, 0x38, 0x08, 0x48, 0x20, 0x1c, 0x9c, 0x13, 0x0f, 0x04, 0x92, 0x33,
    0x5b, 0x4c, 0x4b, 0x7c, 0x03, 0xe2, 0x4f, 0x1f, 0xf7, 0xf5, 0x97, 0xe6, 0x17, 0x6a, 0x0d, 0x72, 0x90, 0xc0,
    0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82
};
// 9 x 5, 1-bit grey
const std::vector<std::uint8_t> kOneBitPng = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00,
    0x00, 0x09, 0x00, 0x00, 0x00, 0x05, 0x01, 0x00, 0x00, 0x00, 0x00, 0xbf, 0x28, 0xfb, 0xc6, 0x00, 0x00, 0x00,
    0x17, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0xcc, 0x90, 0x60, 0x98, 0xc4, 0xc0, 0x68, 0xeb, 0xcc, 0xf4,
    0x98, 0x81, 0xe1, 0x36, 0x03, 0x00, 0x17, 0x43, 0x03, 0x55, 0xf7, 0x50, 0x87, 0x0c, 0x00, 0x00, 0x00, 0x00,
    0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82
};

using photorig::solvers::codecs::test_support::SameBits;

cv::Mat RandomImage(int depth, int channels, int rows = 37, int cols = 53) {
  cv::Mat image(rows, cols, CV_MAKETYPE(depth, channels));
  cv::RNG rng(depth * 10 + channels);
  if (depth == CV_32F) {
    rng.fill(image, cv::RNG::NORMAL, 0.0, 1000.0);
    image.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();
    image.at<float>(0, 1) = -0.0f;
    image.at<float>(0, 2) = std::numeric_limits<float>::infinity();
  } else {
    rng.fill(image, cv::RNG::UNIFORM, 0, depth == CV_8U ? 256 : 65536);
  }
  return image;
}

cv::Mat Decode(const std::vector<std::uint8_t>& bytes, ReadMode mode = ReadMode::kAsStored) {
  std::string why;
  cv::Mat image = DecodeImage(bytes, mode, &why);
  EXPECT_EQ(image.empty(), !why.empty()) << why;
  return image;
}

std::vector<std::uint8_t> Encode(ImageEncoding encoding, const cv::Mat& image, const EncodeOptions& options = {}) {
  std::vector<std::uint8_t> bytes;
  std::string why;
  EXPECT_TRUE(EncodeImage(encoding, image, &bytes, &why, options)) << why;
  return bytes;
}

std::vector<std::uint8_t> OpenCvEncode(const std::string& extension, const cv::Mat& image) {
  std::vector<std::uint8_t> bytes;
  EXPECT_TRUE(cv::imencode(extension, image, bytes));
  return bytes;
}

struct Layout {
  int depth, channels;
};

class EveryLayout : public ::testing::TestWithParam<Layout> {};
class IntegerLayout : public ::testing::TestWithParam<Layout> {};  // PNG has no float samples

TEST_P(IntegerLayout, PngDecodesAsOpenCvAndOpenCvDecodesOurs) {
  const auto [depth, channels] = GetParam();
  const cv::Mat image = RandomImage(depth, channels);
  EXPECT_TRUE(SameBits(Decode(OpenCvEncode(".png", image)), image));
  for (int level : {0, 1, 9}) {
    const std::vector<std::uint8_t> ours = Encode(ImageEncoding::kPng, image, {.png_compression_level = level});
    EXPECT_TRUE(SameBits(cv::imdecode(ours, cv::IMREAD_UNCHANGED), image)) << "level " << level;
    EXPECT_TRUE(SameBits(Decode(ours), image)) << "level " << level;
  }
}

TEST_P(EveryLayout, TiffDecodesAsOpenCvAndOpenCvDecodesOurs) {
  const auto [depth, channels] = GetParam();
  const cv::Mat image = RandomImage(depth, channels);
  // LZW, as float colour must be asked for: OpenCV's default for it is lossy LogLuv.
  std::vector<std::uint8_t> theirs;
  ASSERT_TRUE(cv::imencode(".tiff", image, theirs, {cv::IMWRITE_TIFF_COMPRESSION, 5}));
  EXPECT_TRUE(SameBits(Decode(theirs), image));
  const std::vector<std::uint8_t> ours = Encode(ImageEncoding::kTiff, image);
  EXPECT_TRUE(SameBits(Decode(ours), image));
  // OpenCV 4.6 premultiplies a fourth sample the file marks as unassociated
  // alpha (its own files leave the fourth sample unmarked).
  if (channels != 4) {
    EXPECT_TRUE(SameBits(cv::imdecode(ours, cv::IMREAD_UNCHANGED), image));
  }
}

std::string LayoutName(const ::testing::TestParamInfo<Layout>& info) {
  return std::string(info.param.depth == CV_8U ? "u8" : info.param.depth == CV_16U ? "u16" : "f32") + "x" +
         std::to_string(info.param.channels);
}

INSTANTIATE_TEST_SUITE_P(Codecs, IntegerLayout,
                         ::testing::Values(Layout{CV_8U, 1}, Layout{CV_8U, 3}, Layout{CV_8U, 4}, Layout{CV_16U, 1},
                                           Layout{CV_16U, 3}, Layout{CV_16U, 4}),
                         LayoutName);
INSTANTIATE_TEST_SUITE_P(Codecs, EveryLayout,
                         ::testing::Values(Layout{CV_8U, 1}, Layout{CV_8U, 3}, Layout{CV_8U, 4}, Layout{CV_16U, 1},
                                           Layout{CV_16U, 3}, Layout{CV_16U, 4}, Layout{CV_32F, 1},
                                           Layout{CV_32F, 3}, Layout{CV_32F, 4}),
                         LayoutName);

TEST(Png, VariantsOpenCvDoesNotWriteDecodeAsOpenCvDecodesThem) {
  for (const auto* bytes : {&kPalettePngWithTransparency, &kGreyAlphaPng, &kOneBitPng}) {
    const cv::Mat theirs = cv::imdecode(*bytes, cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(theirs.empty());
    EXPECT_TRUE(SameBits(Decode(*bytes), theirs));
  }
  // What OpenCV gives, said outright: palette with transparency -> B, G, R, A.
  const cv::Mat palette = Decode(kPalettePngWithTransparency);
  EXPECT_EQ(palette.type(), CV_8UC4);
  EXPECT_EQ(Decode(kOneBitPng).type(), CV_8UC1);
}

TEST(Png, TruncatedCorruptAndOversizedFilesAreRefusedWithAReason) {
  const std::vector<std::uint8_t> good = OpenCvEncode(".png", RandomImage(CV_8U, 3));
  std::string why;
  for (std::size_t keep : {std::size_t{8}, std::size_t{20}, std::size_t{40}, good.size() / 2, good.size() - 13}) {
    const std::vector<std::uint8_t> truncated(good.begin(), good.begin() + keep);
    EXPECT_TRUE(DecodeImage(truncated, ReadMode::kAsStored, &why).empty()) << keep;
    EXPECT_NE(why.find("PNG"), std::string::npos) << why;
  }
  std::vector<std::uint8_t> corrupt = good;
  corrupt[60] ^= 0x55;  // inside the image data: its CRC no longer matches
  EXPECT_TRUE(DecodeImage(corrupt, ReadMode::kAsStored, &why).empty());
  EXPECT_NE(why.find("PNG"), std::string::npos) << why;
  // A header asking for 100,000 x 100,000 RGB pixels (30 GB), with its CRC
  // made right: refused before anything is allocated.
  std::vector<std::uint8_t> huge = good;
  const std::uint8_t size[8] = {0, 1, 0x86, 0xa0, 0, 1, 0x86, 0xa0};
  std::memcpy(&huge[16], size, sizeof size);
  const std::uint32_t crc = static_cast<std::uint32_t>(crc32(0, &huge[12], 17));  // the chunk's type and data
  for (int i = 0; i < 4; ++i) huge[29 + i] = static_cast<std::uint8_t>(crc >> (24 - 8 * i));
  EXPECT_TRUE(DecodeImage(huge, ReadMode::kAsStored, &why).empty());
  EXPECT_NE(why.find("1 GiB"), std::string::npos) << why;
}

// A TIFF written by libtiff itself, in layouts OpenCV's encoder does not use.
std::vector<std::uint8_t> LibtiffFile(const cv::Mat& rgb16, bool tiled, bool separate_planes) {
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("photorig_codecs_" + std::to_string(::getpid()) + ".tiff")).string();
  TIFF* tif = TIFFOpen(path.c_str(), "w");
  TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, rgb16.cols);
  TIFFSetField(tif, TIFFTAG_IMAGELENGTH, rgb16.rows);
  TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, 3);
  TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, 16);
  TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_RGB);
  TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_ADOBE_DEFLATE);
  TIFFSetField(tif, TIFFTAG_PLANARCONFIG, separate_planes ? PLANARCONFIG_SEPARATE : PLANARCONFIG_CONTIG);
  std::vector<cv::Mat> planes;
  cv::split(rgb16, planes);  // R, G, B as the file stores them
  if (tiled) {
    TIFFSetField(tif, TIFFTAG_TILEWIDTH, 16);
    TIFFSetField(tif, TIFFTAG_TILELENGTH, 16);
    std::vector<std::uint16_t> tile(16 * 16 * 3);
    for (int y = 0; y < rgb16.rows; y += 16)
      for (int x = 0; x < rgb16.cols; x += 16)
        for (int s = 0; s < (separate_planes ? 3 : 1); ++s) {
          std::fill(tile.begin(), tile.end(), 0);
          for (int r = y; r < std::min(y + 16, rgb16.rows); ++r)
            for (int c = x; c < std::min(x + 16, rgb16.cols); ++c)
              for (int k = 0; k < (separate_planes ? 1 : 3); ++k)
                tile[((r - y) * 16 + (c - x)) * (separate_planes ? 1 : 3) + k] =
                    rgb16.at<cv::Vec3w>(r, c)[separate_planes ? s : k];
          TIFFWriteTile(tif, tile.data(), x, y, 0, static_cast<std::uint16_t>(s));
        }
  } else {
    TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, 5);
    for (int s = 0; s < (separate_planes ? 3 : 1); ++s)
      for (int r = 0; r < rgb16.rows; ++r)
        TIFFWriteScanline(tif, const_cast<std::uint8_t*>(separate_planes ? planes[s].ptr(r) : rgb16.ptr(r)), r,
                          static_cast<std::uint16_t>(s));
  }
  TIFFClose(tif);
  std::ifstream in(path, std::ios::binary);
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::filesystem::remove(path);
  return bytes;
}

// OpenCV 4.6 misreads 16-bit samples in separate planes: those are checked
// against the pixels written alone.
TEST(Tiff, TilesAndSeparatePlanesDecodeToThePixelsWritten) {
  const cv::Mat rgb16 = RandomImage(CV_16U, 3, 37, 41);  // tiles and strips that overhang the edges
  cv::Mat bgr16;
  cv::cvtColor(rgb16, bgr16, cv::COLOR_RGB2BGR);
  for (bool tiled : {false, true})
    for (bool separate : {false, true}) {
      const std::vector<std::uint8_t> bytes = LibtiffFile(rgb16, tiled, separate);
      EXPECT_TRUE(SameBits(Decode(bytes), bgr16)) << "tiled " << tiled << ", separate planes " << separate;
      if (!separate) {
        EXPECT_TRUE(SameBits(Decode(bytes), cv::imdecode(bytes, cv::IMREAD_UNCHANGED))) << "tiled " << tiled;
      }
    }
}

TEST(Tiff, TruncatedFilesAreRefusedWithAReason) {
  const std::vector<std::uint8_t> good = Encode(ImageEncoding::kTiff, RandomImage(CV_32F, 3, 300, 200));
  std::string why;
  for (std::size_t keep : {std::size_t{4}, std::size_t{8}, std::size_t{100}, good.size() / 2, good.size() - 40}) {
    const std::vector<std::uint8_t> truncated(good.begin(), good.begin() + keep);
    EXPECT_TRUE(DecodeImage(truncated, ReadMode::kAsStored, &why).empty()) << keep;
    EXPECT_NE(why.find("TIFF"), std::string::npos) << why;
  }
}

TEST(ReadModes, AlphaDroppedAndGreyAsOpenCvReadsThem) {
  const cv::Mat bgra = RandomImage(CV_8U, 4);
  const std::vector<std::uint8_t> png = Encode(ImageEncoding::kPng, bgra);
  cv::Mat bgr;
  cv::cvtColor(bgra, bgr, cv::COLOR_BGRA2BGR);
  EXPECT_TRUE(SameBits(Decode(png, ReadMode::kWithoutAlpha), bgr));
  EXPECT_TRUE(SameBits(Decode(png, ReadMode::kWithoutAlpha), cv::imdecode(png, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR)));
  // OpenCV's PNG reader makes grey inside libpng, with its own rounding:
  // within 1 DN of 8 bits, 8 DN of 16 (0.01 %).
  for (int depth : {CV_8U, CV_16U}) {
    const std::vector<std::uint8_t> colour = Encode(ImageEncoding::kPng, RandomImage(depth, 3));
    const cv::Mat grey = Decode(colour, ReadMode::kGrey);
    const cv::Mat theirs = cv::imdecode(colour, cv::IMREAD_ANYDEPTH | cv::IMREAD_GRAYSCALE);
    ASSERT_EQ(grey.type(), theirs.type());
    cv::Mat difference;
    cv::absdiff(grey, theirs, difference);
    double most = 0;
    cv::minMaxLoc(difference, nullptr, &most);
    EXPECT_LE(most, depth == CV_8U ? 1.0 : 8.0) << "depth " << depth;
  }
  // Grey stays as stored whatever the mode.
  const cv::Mat grey16 = RandomImage(CV_16U, 1);
  for (ReadMode mode : {ReadMode::kAsStored, ReadMode::kWithoutAlpha, ReadMode::kGrey})
    EXPECT_TRUE(SameBits(Decode(Encode(ImageEncoding::kTiff, grey16), mode), grey16));
}

TEST(ImageCodecs, EncodingByExtensionAndRefusals) {
  EXPECT_EQ(EncodingOfPath("a/b.PNG"), ImageEncoding::kPng);
  EXPECT_EQ(EncodingOfPath("normals.tiff"), ImageEncoding::kTiff);
  EXPECT_EQ(EncodingOfPath("x.Tif"), ImageEncoding::kTiff);
  EXPECT_EQ(EncodingOfPath("map.hdr"), ImageEncoding::kRadianceHdr);
  EXPECT_EQ(EncodingOfPath("albedo.exr"), ImageEncoding::kOpenExr);
  EXPECT_FALSE(EncodingOfPath("photo.jpg"));
  EXPECT_FALSE(EncodingOfPath("png"));
  std::vector<std::uint8_t> bytes;
  std::string why;
  EXPECT_FALSE(EncodeImage(ImageEncoding::kPng, RandomImage(CV_32F, 1), &bytes, &why));
  EXPECT_FALSE(why.empty());
  EXPECT_FALSE(EncodeImage(ImageEncoding::kPng, RandomImage(CV_8U, 1), &bytes, &why, {.png_compression_level = 10}));
  EXPECT_NE(why.find("10"), std::string::npos) << why;
  EXPECT_FALSE(EncodeImage(ImageEncoding::kTiff, cv::Mat(4, 4, CV_64F), &bytes, &why));
  EXPECT_TRUE(bytes.empty());
  const std::vector<std::uint8_t> text = {'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd', '!', '!', '!', '!', '!'};
  EXPECT_TRUE(DecodeImage(text, ReadMode::kAsStored, &why).empty());
  EXPECT_NE(why.find("PNG, TIFF"), std::string::npos) << why;
}

// DecodeOptions' limit holds for every format: an image of exactly that
// many pixel bytes (as stored) decodes, one byte less refuses it before
// decoding and says the limit; options out of range are refused.
TEST(DecodeOptions, EveryFormatKeepsToThePixelLimit) {
  const cv::Mat colour = [] {
    cv::Mat image(48, 64, CV_8UC3);
    cv::randu(image, 0, 256);
    return image;
  }();
  cv::Mat hdr;
  colour.convertTo(hdr, CV_32F, 1.0 / 255);
  for (const auto& [extension, image] : std::vector<std::pair<std::string, cv::Mat>>{
           {".png", colour}, {".tiff", colour}, {".jpg", colour}, {".bmp", colour}, {".ppm", colour}, {".hdr", hdr}}) {
    std::vector<std::uint8_t> bytes;
    ASSERT_TRUE(cv::imencode(extension, image, bytes)) << extension;
    const std::uint64_t pixel_bytes = image.total() * image.elemSize();
    std::string why;
    EXPECT_FALSE(DecodeImage(bytes, DecodeOptions{.max_pixel_bytes = pixel_bytes}, &why).empty())
        << extension << ": " << why;
    why.clear();
    EXPECT_TRUE(DecodeImage(bytes, DecodeOptions{.max_pixel_bytes = pixel_bytes - 1}, &why).empty()) << extension;
    EXPECT_NE(why.find("past the " + std::to_string(pixel_bytes - 1) + " bytes limit"), std::string::npos)
        << extension << ": " << why;
    // The read mode applies after the limit, which is the stored image's.
    const cv::Mat grey = DecodeImage(bytes, DecodeOptions{.mode = ReadMode::kGrey, .max_pixel_bytes = pixel_bytes}, &why);
    EXPECT_EQ(grey.channels(), 1) << extension << ": " << why;
  }
  std::string why;
  EXPECT_FALSE(DecodeOptions{.max_pixel_bytes = 0}.IsValid(&why));
  EXPECT_EQ(why, "max_pixel_bytes 0 is not in 1-1073741824");
  EXPECT_FALSE(DecodeOptions{.max_pixel_bytes = kMaxDecodedBytes + 1}.IsValid(&why));
  EXPECT_TRUE(DecodeOptions{}.IsValid(&why));
  std::vector<std::uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", colour, png));
  why.clear();
  EXPECT_TRUE(DecodeImage(png, DecodeOptions{.max_pixel_bytes = 0}, &why).empty());
  EXPECT_EQ(why, "max_pixel_bytes 0 is not in 1-1073741824");
}

}  // namespace
}  // namespace photorig::solvers::codecs
