#include "photorig/solvers/codecs/image_codecs.h"

#include "formats.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cctype>
#include <filesystem>

namespace photorig::solvers::codecs {

std::string internal::LimitText(std::uint64_t bytes) {
  constexpr std::uint64_t kMiB = std::uint64_t{1} << 20, kGiB = std::uint64_t{1} << 30;
  if (bytes % kGiB == 0) return std::to_string(bytes / kGiB) + " GiB";
  if (bytes % (kGiB / 2) == 0) return std::to_string(bytes / kGiB) + ".5 GiB";
  if (bytes % kMiB == 0) return std::to_string(bytes / kMiB) + " MiB";
  return std::to_string(bytes) + " bytes";
}

namespace {

cv::Mat DecodeAsStored(std::span<const std::uint8_t> bytes, std::uint64_t max_pixel_bytes, std::string* why) {
  using core::ImageFileFormat;
  switch (core::ImageFileFormatOf(bytes)) {
    case ImageFileFormat::kPng: return internal::DecodePng(bytes, why, max_pixel_bytes);
    case ImageFileFormat::kTiff: return internal::DecodeTiff(bytes, why, max_pixel_bytes);
    case ImageFileFormat::kJpeg: return internal::DecodeJpeg(bytes, why, max_pixel_bytes);
    case ImageFileFormat::kBmp: return internal::DecodeBmp(bytes, why, max_pixel_bytes);
    case ImageFileFormat::kPnm: return internal::DecodePnm(bytes, why, max_pixel_bytes);
    case ImageFileFormat::kRadianceHdr: return internal::DecodeRadianceHdr(bytes, why, max_pixel_bytes);
    case ImageFileFormat::kUnknown: break;
  }
  *why = std::string("not one of the formats read (") + core::ReadableImageFormats() + ")";
  return {};
}

}  // namespace

bool DecodeOptions::IsValid(std::string* why) const {
  if (max_pixel_bytes == 0 || max_pixel_bytes > kMaxDecodedBytes) {
    *why = "max_pixel_bytes " + std::to_string(max_pixel_bytes) + " is not in 1-" + std::to_string(kMaxDecodedBytes);
    return false;
  }
  return true;
}

cv::Mat DecodeImage(std::span<const std::uint8_t> bytes, ReadMode mode, std::string* why) {
  return DecodeImage(bytes, DecodeOptions{.mode = mode}, why);
}

cv::Mat DecodeImage(std::span<const std::uint8_t> bytes, const DecodeOptions& options, std::string* why) {
  if (!options.IsValid(why)) return {};
  cv::Mat image = DecodeAsStored(bytes, options.max_pixel_bytes, why);
  const ReadMode mode = options.mode;
  if (image.empty() || mode == ReadMode::kAsStored || image.channels() == 1) return image;
  cv::Mat kept;
  if (mode == ReadMode::kGrey) {
    cv::cvtColor(image, kept, image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
    return kept;
  }
  if (image.channels() != 4) return image;
  cv::cvtColor(image, kept, cv::COLOR_BGRA2BGR);
  return kept;
}

std::optional<ImageEncoding> EncodingOfPath(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".png") return ImageEncoding::kPng;
  if (extension == ".tif" || extension == ".tiff") return ImageEncoding::kTiff;
  if (extension == ".hdr") return ImageEncoding::kRadianceHdr;
  if (extension == ".exr") return ImageEncoding::kOpenExr;
  return std::nullopt;
}

bool EncodeOptions::IsValid(std::string* why) const {
  if (png_compression_level < 0 || png_compression_level > 9) {
    *why = "png_compression_level " + std::to_string(png_compression_level) + " is not in 0-9";
    return false;
  }
  return true;
}

bool EncodeImage(ImageEncoding encoding, const cv::Mat& image, std::vector<std::uint8_t>* out, std::string* why,
                 const EncodeOptions& options) {
  if (!options.IsValid(why)) return false;
  switch (encoding) {
    case ImageEncoding::kPng: return internal::EncodePng(image, options.png_compression_level, out, why);
    case ImageEncoding::kTiff: return internal::EncodeTiff(image, out, why);
    case ImageEncoding::kRadianceHdr: return internal::EncodeRadianceHdr(image, out, why);
    case ImageEncoding::kOpenExr: return internal::EncodeOpenExr(image, out, why);
  }
  *why = "unknown encoding";
  return false;
}

}  // namespace photorig::solvers::codecs
