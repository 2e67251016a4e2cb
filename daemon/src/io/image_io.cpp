#include "photorig/daemon/io/image_io.h"

#include "photorig/solvers/core/image_file_format.h"

#include <opencv2/imgproc.hpp>
#include <libdeflate.h>

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <system_error>
#include <thread>

namespace photorig::daemon {
namespace fs = std::filesystem;
using solvers::codecs::ReadMode;
namespace {

// A system_error keeps errno, so callers can tell a full disk from other failures.
[[noreturn]] void Fail(const std::string& what, const std::string& path) {
  throw std::system_error(errno, std::generic_category(), what + " " + path);
}

}  // namespace

void FsyncDirectory(const std::string& directory) {
  const int fd = ::open(directory.empty() ? "." : directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) Fail("cannot open directory", directory);
  const int synced = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  errno = error;
  if (synced != 0) Fail("cannot fsync directory", directory);
}

// Temp file, fsync, rename, fsync of the directory: readers and crashes see
// the whole file or none.
void WriteFileDurably(const std::string& path, const void* data, std::size_t size) {
  const std::string temp = path + ".tmp";
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) Fail("cannot create", temp);
  const char* bytes = static_cast<const char*>(data);
  std::size_t written = 0;
  // A failed write (a full disk) leaves no temp file holding the space.
  auto fail = [&](const char* what, const std::string& name) {
    const int error = errno;
    ::close(fd);
    ::unlink(temp.c_str());
    errno = error;
    Fail(what, name);
  };
  while (written < size) {
    const ssize_t n = ::write(fd, bytes + written, size - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("cannot write", temp);
    }
    written += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) fail("cannot fsync", temp);
  ::close(fd);
  if (::rename(temp.c_str(), path.c_str()) != 0) {
    const int error = errno;
    ::unlink(temp.c_str());
    errno = error;
    Fail("cannot rename into", path);
  }
  FsyncDirectory(fs::path(path).parent_path().string());
}

void WriteFileDurably(const std::string& path, const std::string& text) {
  WriteFileDurably(path, text.data(), text.size());
}

void WriteImage(const std::string& path, const cv::Mat& image, const solvers::codecs::EncodeOptions& options) {
  const auto encoding = solvers::codecs::EncodingOfPath(path);
  if (!encoding)
    throw std::runtime_error("cannot write image " + path + ": its extension names no format written (.png, .tiff, "
                             ".hdr, .exr)");
  std::vector<std::uint8_t> bytes;
  std::string why;
  if (!solvers::codecs::EncodeImage(*encoding, image, &bytes, &why, options))
    throw std::runtime_error("cannot encode image for " + path + ": " + why);
  WriteFileDurably(path, bytes.data(), bytes.size());
}

void WriteFloatTiff(const std::string& path, const cv::Mat& image) {
  if (image.depth() != CV_32F || (image.channels() != 1 && image.channels() != 3))
    throw std::invalid_argument("WriteFloatTiff " + path + ": expected a 1- or 3-channel float image");
  if (image.channels() == 1) return WriteImage(path, image);
  cv::Mat bgr;  // OpenCV stores BGR in memory and RGB in the file
  cv::cvtColor(image, bgr, cv::COLOR_RGB2BGR);
  WriteImage(path, bgr);
}

cv::Mat TryReadImage(const std::string& path, ReadMode mode, std::string* why) {
  std::vector<std::uint8_t> bytes;
  if (!solvers::core::ReadImageFileBytes(path, &bytes, why)) return {};
  return solvers::codecs::DecodeImage(bytes, mode, why);
}

cv::Mat ReadImage(const std::string& path, ReadMode mode) {
  std::string why;
  cv::Mat image = TryReadImage(path, mode, &why);
  if (image.empty()) throw std::runtime_error("cannot read image " + path + " (" + why + ")");
  return image;
}

cv::Mat ReadInputImage(const std::string& path, ReadMode mode) {
  std::string why;
  cv::Mat image = TryReadImage(path, mode, &why);
  if (image.empty()) throw std::invalid_argument("cannot read image " + path + " (" + why + ")");
  return image;
}

cv::Mat ReadFloatTiff(const std::string& path) {
  cv::Mat image = ReadImage(path);
  if (image.depth() != CV_32F) throw std::runtime_error(path + ": expected a float image");
  if (image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2RGB);
  return image;
}

cv::Mat AllocateFrameSlab(int count, cv::Size size, int type) {
  cv::Mat slab(count * size.height, size.width, type);
  // Advice only for whole 2 MB pages inside the allocation, before any is
  // touched; a kernel without transparent huge pages refuses it, and the
  // slab is then an ordinary allocation.
  constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;
  const auto begin = reinterpret_cast<std::uintptr_t>(slab.data);
  const std::uintptr_t end = begin + slab.total() * slab.elemSize();
  const std::uintptr_t first = (begin + kHugePage - 1) & ~(kHugePage - 1), last = end & ~(kHugePage - 1);
  if (last > first) madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
  return slab;
}

cv::Mat FrameOfSlab(const cv::Mat& slab, int frame, int rows) { return slab.rowRange(frame * rows, (frame + 1) * rows); }

std::vector<std::exception_ptr> LoadOnEveryCore(std::size_t count, const std::function<void(std::size_t)>& load) {
  std::vector<std::exception_ptr> failures(count);
  std::atomic<std::size_t> next{0};
  auto work = [&] {
    for (std::size_t i; (i = next++) < count;) try {
        load(i);
      } catch (...) {
        failures[i] = std::current_exception();
      }
  };
  const std::size_t workers = std::min<std::size_t>(std::max(1u, std::thread::hardware_concurrency()), count);
  std::vector<std::thread> helpers;
  for (std::size_t w = 1; w < workers; ++w) helpers.emplace_back(work);
  work();
  for (std::thread& helper : helpers) helper.join();
  return failures;
}

cv::Mat NormalsToBgr8(const cv::Mat& normals) {
  cv::Mat out(normals.size(), CV_8UC3, cv::Scalar::all(0));
  for (int r = 0; r < normals.rows; ++r) {
    const auto* n = normals.ptr<cv::Vec3f>(r);
    auto* o = out.ptr<cv::Vec3b>(r);
    for (int c = 0; c < normals.cols; ++c) {
      if (!std::isfinite(n[c][0])) continue;
      auto to8 = [](float v) { return cv::saturate_cast<std::uint8_t>((v + 1.0f) * 127.5f); };
      o[c] = cv::Vec3b(to8(n[c][2]), to8(n[c][1]), to8(n[c][0]));  // B = z, G = y, R = x
    }
  }
  return out;
}

std::uint32_t Crc32(const void* data, std::size_t size, std::uint32_t crc) {
  return libdeflate_crc32(crc, data, size);
}

}  // namespace photorig::daemon
