// Which format a file's first bytes name: each readable format's signature as
// its encoder writes it, and what must never reach a decoder (DICOM's mark at
// byte 128, OpenEXR, text, short files).

#include "photorig/solvers/core/image_file_format.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace photorig::solvers::core {
namespace {

ImageFileFormat FormatOf(const std::string& bytes) {
  const std::vector<std::uint8_t> head(bytes.begin(), bytes.end());
  return ImageFileFormatOf(head);
}

TEST(ImageFileFormat, EachReadableFormatIsNamedByItsSignature) {
  using namespace std::string_literals;
  EXPECT_EQ(FormatOf("\x89PNG\r\n\x1a\n\0\0\0\rIHDR"s), ImageFileFormat::kPng);
  EXPECT_EQ(FormatOf("II*\0\x08\0\0\0"s), ImageFileFormat::kTiff);
  EXPECT_EQ(FormatOf("MM\0*\0\0\0\x08"s), ImageFileFormat::kTiff);
  EXPECT_EQ(FormatOf("II+\0\x08\0\0\0"s), ImageFileFormat::kTiff);  // BigTIFF
  EXPECT_EQ(FormatOf("\xff\xd8\xff\xe0\0\x10JFIF"s), ImageFileFormat::kJpeg);
  EXPECT_EQ(FormatOf("BM\x36\x10\0\0"s), ImageFileFormat::kBmp);
  EXPECT_EQ(FormatOf("P5\n8 8\n65535\n"), ImageFileFormat::kPnm);
  EXPECT_EQ(FormatOf("P7\nWIDTH 8\n"), ImageFileFormat::kPnm);
  EXPECT_EQ(FormatOf("Pf\n8 8\n-1\n"), ImageFileFormat::kPnm);
  EXPECT_EQ(FormatOf("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n"), ImageFileFormat::kRadianceHdr);
  EXPECT_EQ(FormatOf("#?RGBE\n"), ImageFileFormat::kRadianceHdr);
}

TEST(ImageFileFormat, DicomExrTextAndShortFilesAreNamedNone) {
  using namespace std::string_literals;
  // DICOM: a 128-byte preamble, then "DICM"; the decoder OpenCV would give it to aborts on a malformed one.
  EXPECT_EQ(FormatOf(std::string(128, '\0') + "DICM\x02\0\0\0"s), ImageFileFormat::kUnknown);
  EXPECT_EQ(FormatOf(std::string(128, '\xca') + "DICM1\n"), ImageFileFormat::kUnknown);
  EXPECT_EQ(FormatOf("v/1\x01\x02\0\0\0"s), ImageFileFormat::kUnknown);  // OpenEXR
  EXPECT_EQ(FormatOf("\0\0\0\x0cjP  \r\n\x87\n"s), ImageFileFormat::kUnknown);  // JPEG 2000
  EXPECT_EQ(FormatOf("RIFF\0\0\0\0WEBPVP8 "s), ImageFileFormat::kUnknown);
  EXPECT_EQ(FormatOf("P8\n"), ImageFileFormat::kUnknown);
  EXPECT_EQ(FormatOf("P5"), ImageFileFormat::kUnknown);        // no white space after the magic
  EXPECT_EQ(FormatOf("\x89PNG\r\n"), ImageFileFormat::kUnknown);  // cut inside the signature
  EXPECT_EQ(FormatOf(""), ImageFileFormat::kUnknown);
  EXPECT_EQ(FormatOf("0.3 0.2 0.93\n"), ImageFileFormat::kUnknown);
}

}  // namespace
}  // namespace photorig::solvers::core
