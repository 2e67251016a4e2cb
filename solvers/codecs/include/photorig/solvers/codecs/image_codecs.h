#pragma once
// Image files to pixels and back, in OpenCV's layout (grey; B, G, R; B, G,
// R, A), on Debian's codec libraries (libpng, libtiff, libjpeg-turbo,
// OpenEXR) and short readers of the project's own for PNM, BMP and Radiance
// HDR. OpenCV's image codec module is not used: its plugins (GDAL, GDCM,
// HEIF and what they need) bind about 120 shared libraries when any program
// linking it starts: `photorig --help` took 0.24 s with them, 0.13 s without.
//
// Decoding is pure computation on bytes already read (ReadImageFileBytes in
// photorig/solvers/core/image_file_format.h reads them and refuses what is
// not one of the formats); writing files durably is the caller's.

#include "photorig/solvers/core/image_file_format.h"

#include <opencv2/core.hpp>

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace photorig::solvers::codecs {

// What of the stored image a reader keeps.
enum class ReadMode {
  kAsStored,      // channels and depth as stored: 1, 3 or 4 channels; 8-bit, 16-bit or float
  kWithoutAlpha,  // as stored, a fourth (alpha) channel dropped
  kGrey,          // one channel at the stored depth (colour as 0.299 R + 0.587 G + 0.114 B)
};

// The largest decoded image a reader accepts, in bytes of pixels: image
// files are read whole up to 1 GiB as well, and no frame of this project
// comes near it.
inline constexpr std::uint64_t kMaxDecodedBytes = std::uint64_t{1} << 30;

struct DecodeOptions {
  ReadMode mode = ReadMode::kAsStored;
  // A header asking for more pixel bytes than this is refused before
  // anything is allocated (a JPEG's decoder may use half as much again for
  // its buffers). Default kMaxDecodedBytes, the most allowed. A caller that
  // knows its frames sets less: a small file may legally claim a large image,
  // and an arithmetic-coded JPEG of a few hundred bytes takes seconds to
  // decode into 1 GiB.
  std::uint64_t max_pixel_bytes = kMaxDecodedBytes;

  bool IsValid(std::string* why) const;
};

// Decodes `bytes` as the format their first bytes name (ImageFileFormatOf):
// PNG (1-16 bits, palettes expanded), TIFF (8/16-bit unsigned and float
// samples as stored; palette, bilevel, YCbCr and CMYK as 8-bit colour), JPEG
// (8-bit grey or colour; EXIF orientation not applied: pixels as the sensor
// gave them), BMP, PNM (P1-P6, 8- or 16-bit) and Radiance HDR (float colour).
// An empty Mat and `why` (the format and what is wrong: truncated, corrupt,
// a variant not read, past the limit, invalid options) otherwise; never throws.
cv::Mat DecodeImage(std::span<const std::uint8_t> bytes, const DecodeOptions& options, std::string* why);
// The same with the default limit.
cv::Mat DecodeImage(std::span<const std::uint8_t> bytes, ReadMode mode, std::string* why);

// Formats written: PNG (8/16-bit, 1/3/4 channels), TIFF (LZW; 8/16-bit or
// float, 1/3/4 channels), Radiance HDR (float, 1 or 3 channels) and OpenEXR
// (32-bit float, 1 or 3 channels).
enum class ImageEncoding { kPng, kTiff, kRadianceHdr, kOpenExr };

// The encoding a path's extension names (.png, .tif/.tiff, .hdr, .exr; any
// case); nullopt for any other.
std::optional<ImageEncoding> EncodingOfPath(const std::string& path);

struct EncodeOptions {
  // zlib level for PNG, 0-9. 1 (default): the fastest level that compresses,
  // for previews, masks and textures written while a person waits.
  int png_compression_level = 1;

  bool IsValid(std::string* why) const;
};

// Appends the encoded file to `out`; false and `why` for an image the format
// cannot hold (depth, channels, empty) or invalid options.
bool EncodeImage(ImageEncoding encoding, const cv::Mat& image, std::vector<std::uint8_t>* out, std::string* why,
                 const EncodeOptions& options = {});

}  // namespace photorig::solvers::codecs
