#pragma once
// Each format's decoder and encoder, for image_codecs.cpp, which picks one by
// the file's first bytes (decoding) or the path's extension (encoding) and
// applies the read mode. Decoders return the image as the file stores it, in
// OpenCV's conventions: 1 channel (grey), 3 (B, G, R) or 4 (B, G, R, A);
// CV_8U, CV_16U (native byte order) or CV_32F. An empty Mat and `why` for a
// truncated, corrupt or unsupported file; they never throw and never read
// past `bytes`.

#include <opencv2/core.hpp>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace photorig::solvers::codecs::internal {

// Each decoder refuses a header asking for more than max_pixel_bytes of
// pixels before anything is allocated (DecodeOptions: at most
// kMaxDecodedBytes, which image_codecs.h defines).
cv::Mat DecodePng(std::span<const std::uint8_t> bytes, std::string* why, std::uint64_t max_pixel_bytes);
cv::Mat DecodeTiff(std::span<const std::uint8_t> bytes, std::string* why, std::uint64_t max_pixel_bytes);
cv::Mat DecodeJpeg(std::span<const std::uint8_t> bytes, std::string* why, std::uint64_t max_pixel_bytes);
cv::Mat DecodeBmp(std::span<const std::uint8_t> bytes, std::string* why, std::uint64_t max_pixel_bytes);
cv::Mat DecodePnm(std::span<const std::uint8_t> bytes, std::string* why, std::uint64_t max_pixel_bytes);
// Radiance RGBE: CV_32FC3 (B, G, R).
cv::Mat DecodeRadianceHdr(std::span<const std::uint8_t> bytes, std::string* why,
                          std::uint64_t max_pixel_bytes);

// A limit as the decoders' reasons name it: "1 GiB", "1.5 GiB", "64 MiB", or bytes.
std::string LimitText(std::uint64_t bytes);

// Encoders append the whole file to `out`; false and `why` for an image the
// format cannot hold (its depth or channel count).
// PNG: CV_8U or CV_16U, 1, 3 (B, G, R) or 4 (B, G, R, A) channels; zlib
// level 0-9.
bool EncodePng(const cv::Mat& image, int compression_level, std::vector<std::uint8_t>* out, std::string* why);
// TIFF, LZW-compressed: CV_8U, CV_16U or CV_32F, 1, 3 (B, G, R) or 4 channels.
bool EncodeTiff(const cv::Mat& image, std::vector<std::uint8_t>* out, std::string* why);
// Radiance RGBE, run-length encoded scanlines (flat where the width is outside
// 8-32767): CV_32FC3 (B, G, R) or CV_32FC1 (grey).
bool EncodeRadianceHdr(const cv::Mat& image, std::vector<std::uint8_t>* out, std::string* why);
// OpenEXR, 32-bit float channels: CV_32FC1 (channel Y) or CV_32FC3 (B, G, R in
// memory; channels R, G, B in the file).
bool EncodeOpenExr(const cv::Mat& image, std::vector<std::uint8_t>* out, std::string* why);

}  // namespace photorig::solvers::codecs::internal
