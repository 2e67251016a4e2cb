#pragma once
// Image files written by runs and solvers, decoded and encoded by
// photorig/solvers/codecs/image_codecs.h. Float images go to TIFF with
// lossless LZW compression. Normal maps are stored with channels (R, G, B) =
// (x, y, z).

#include "photorig/solvers/codecs/image_codecs.h"

#include <opencv2/core.hpp>

#include <cstddef>
#include <exception>
#include <functional>
#include <string>
#include <vector>

namespace photorig::daemon {

// Writes bytes to `path` so that after a crash the file is either absent or
// complete: temp file, fsync, rename, fsync of the directory. Throws
// std::system_error carrying errno (ENOSPC for a full disk), having removed
// the temp file.
void WriteFileDurably(const std::string& path, const void* data, std::size_t size);
void WriteFileDurably(const std::string& path, const std::string& text);
// Makes a directory's entries (files created, renamed or removed in it) durable.
void FsyncDirectory(const std::string& directory);

// Encodes in the format the extension names (.png, .tif/.tiff, .hdr, .exr;
// photorig/solvers/codecs/image_codecs.h) and writes durably. Throws
// std::runtime_error naming the file and the reason on failure.
void WriteImage(const std::string& path, const cv::Mat& image, const solvers::codecs::EncodeOptions& options = {});
// 1- or 3-channel CV_32F; 3-channel images are taken as (x, y, z).
void WriteFloatTiff(const std::string& path, const cv::Mat& image);
// Reads back what WriteFloatTiff wrote (channels in x, y, z order).
cv::Mat ReadFloatTiff(const std::string& path);
// Reads a PNG, TIFF, JPEG, BMP, PNM or Radiance HDR file, by default as
// stored (16-bit PNG stays 16-bit). Any other file, one whose format its
// first bytes do not name among those, is refused undecoded. Throws
// std::runtime_error naming the file.
cv::Mat ReadImage(const std::string& path, solvers::codecs::ReadMode mode = solvers::codecs::ReadMode::kAsStored);
// The same without throwing: an empty image, and in `why` the reason
// (missing, not a regular file, not one of those formats, truncated or corrupt).
cv::Mat TryReadImage(const std::string& path, solvers::codecs::ReadMode mode, std::string* why);
// The same for an image a request names (a capture, a board, a sphere): one
// that cannot be read is the request's fault, so std::invalid_argument.
cv::Mat ReadInputImage(const std::string& path, solvers::codecs::ReadMode mode = solvers::codecs::ReadMode::kAsStored);

// `count` frames of one size and type in one allocation, frame i as rows
// [i * size.height, (i + 1) * size.height) (FrameOfSlab): each continuous,
// each sharing the allocation's reference count. The kernel is asked to back
// it with 2 MB pages (MADV_HUGEPAGE, where transparent huge pages are
// allowed at all): a 96-light stack of 612 x 512 colour frames is 480 MB,
// 120,000 first-touch faults in 4 KB pages, a quarter of loading it.
cv::Mat AllocateFrameSlab(int count, cv::Size size, int type);
cv::Mat FrameOfSlab(const cv::Mat& slab, int frame, int rows);
// Runs load(i) for every i in [0, count) on all cores (decoding and checking
// a stack's image files is most of loading it) and returns what each call
// threw (null where none), so that the caller reports faults in its own order.
std::vector<std::exception_ptr> LoadOnEveryCore(std::size_t count, const std::function<void(std::size_t)>& load);

// 8-bit view for people: normals as RGB = (n + 1) / 2 (other views: previews.h).
cv::Mat NormalsToBgr8(const cv::Mat& normals);

// CRC-32 of `data`, continuing `crc` (the CRC-32 of the bytes before it; 0 to start).
std::uint32_t Crc32(const void* data, std::size_t size, std::uint32_t crc = 0);

}  // namespace photorig::daemon
