#include "photorig/daemon/pipelines/internal/results_folder.h"

#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/capture/plan.h"

#include <fcntl.h>
#include <stdio.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace photorig::daemon {
namespace fs = std::filesystem;
namespace {

std::string PartialPrefix(const fs::path& destination) {
  std::string prefix = ".";
  prefix += destination.filename().string();
  prefix += ".partial-";
  return prefix;
}

std::string HostName() {
  char name[256] = {};
  ::gethostname(name, sizeof(name) - 1);
  return name;
}

// Less than this free after a failed write: the disk is what failed.
constexpr std::uint64_t kNearlyFullBytes = 1 << 20;

bool IsOutOfSpace(const std::error_code& code) {
  return code == std::errc::no_space_on_device || code.value() == EDQUOT;
}

}  // namespace

ResultsWriteError::ResultsWriteError(const std::string& destination, const std::string& cause, bool disk_full)
    : std::runtime_error("cannot write the results to " + destination + ": " + cause + "; nothing was put there" +
                         (disk_full ? " (the filesystem holding it is full: free space on it, then solve again)"
                                    : " (fix that, then solve again)")),
      destination(destination),
      cause(cause),
      disk_full(disk_full) {}

ResultsFolder::ResultsFolder(const std::string& destination) {
  // "results/ps/" and "results/ps" name the same folder; its parent holds the partial one.
  const fs::path target = fs::absolute(destination).lexically_normal();
  const fs::path normal = target.filename().empty() ? target.parent_path() : target;
  destination_ = normal.string();
  std::error_code error;
  // A file (not a folder) there would be exchanged for the results and lost.
  if (fs::exists(fs::symlink_status(normal, error)) && !fs::is_directory(normal, error))
    throw std::invalid_argument(destination_ + " is a file, not a folder: give a new or empty output folder");
  if (fs::is_directory(normal, error) && !fs::is_empty(normal, error) && !fs::exists(normal / "report.json", error))
    throw std::invalid_argument(destination_ + " holds files that are not a solver's results (no report.json); "
                             "give a new or empty output folder");
  fs::create_directories(normal.parent_path());
  const std::string prefix = PartialPrefix(normal);
  for (const fs::directory_entry& entry : fs::directory_iterator(normal.parent_path()))
    if (entry.path().filename().string().rfind(prefix, 0) == 0) fs::remove_all(entry.path(), error);
  partial_ = (normal.parent_path() / (prefix + HostName() + "-" + std::to_string(::getpid()))).string();
  if (!fs::create_directories(partial_, error) && error)
    throw ResultsWriteError(destination_, "cannot create " + partial_ + ": " + error.message(), IsOutOfSpace(error));
}

ResultsFolder::~ResultsFolder() {
  if (committed_) return;
  std::error_code ignored;
  fs::remove_all(partial_, ignored);
}

void ResultsFolder::Commit() {
  // Every file in it was written durably (WriteFileDurably); the folder's own entry too.
  FsyncDirectory(partial_);
  std::error_code error;
  if (fs::exists(destination_, error)) {
    // One atomic step: the previous result and the new one trade places.
    if (::renameat2(AT_FDCWD, partial_.c_str(), AT_FDCWD, destination_.c_str(), RENAME_EXCHANGE) != 0) {
      if (errno != EINVAL && errno != ENOSYS)
        throw std::runtime_error("cannot put " + partial_ + " in place of " + destination_ + ": " + std::strerror(errno));
      // A filesystem without exchange (some network filesystems): set the old
      // one aside first; a crash between the renames leaves no result at the
      // destination, never a partial one.
      const std::string aside = partial_ + ".previous";
      if (::rename(destination_.c_str(), aside.c_str()) != 0 || ::rename(partial_.c_str(), destination_.c_str()) != 0)
        throw std::runtime_error("cannot put " + partial_ + " in place of " + destination_ + ": " + std::strerror(errno));
      fs::remove_all(aside, error);
    }
  } else if (::rename(partial_.c_str(), destination_.c_str()) != 0) {
    throw std::runtime_error("cannot rename " + partial_ + " to " + destination_ + ": " + std::strerror(errno));
  }
  committed_ = true;
  FsyncDirectory(fs::path(destination_).parent_path().string());
  // After an exchange the previous result sits at the partial folder's name.
  fs::remove_all(partial_, error);
}

void ResultsFolder::Abandon(std::exception_ptr error) {
  // Measured before the partial folder goes: a writer that fails without
  // errno (an encoder, a stream) leaves its part-written file there.
  const bool no_room = FreeBytes(fs::path(destination_).parent_path().string()) < kNearlyFullBytes;
  std::error_code ignored;
  fs::remove_all(partial_, ignored);
  try {
    std::rethrow_exception(error);
  } catch (const ResultsWriteError& e) {  // a folder inside this one (svbrdf's ps/)
    throw ResultsWriteError(destination_, e.cause, e.disk_full || no_room);
  } catch (const std::system_error& e) {  // includes std::filesystem::filesystem_error
    throw ResultsWriteError(destination_, e.what(), IsOutOfSpace(e.code()) || no_room);
  } catch (const std::exception& e) {
    if (!no_room) throw;
    throw ResultsWriteError(destination_, e.what(), true);
  }
}

}  // namespace photorig::daemon
