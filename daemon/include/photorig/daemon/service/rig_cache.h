#pragma once
// The daemon's rig, loaded from its file once and again only when the file
// changes: every dry-run and submit checks its recipe against the rig, and
// parsing the rig (its LEDs, its colour model) costs more than most requests.

#include "photorig/config/rig.h"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace photorig::daemon {

class RigFileCache {
 public:
  explicit RigFileCache(std::string rig_path) : rig_path_(std::move(rig_path)) {}

  // The rig as its file is now. It is loaded again when the rig file or the
  // colour model it names has another modification time or size than at the
  // last load (or cannot be looked at), so an edit takes effect at the next
  // request. Throws what config::LoadRigConfig throws; a failed load is not
  // kept. Safe to call from several threads.
  std::shared_ptr<const config::RigConfig> Get();

 private:
  struct FileIdentity {
    std::string path;
    std::filesystem::file_time_type modified;
    std::uintmax_t size_bytes = 0;
  };
  // nullopt when the file cannot be looked at (gone, no permission): then
  // only loading it says what is wrong.
  static std::optional<FileIdentity> IdentityOf(const std::string& path);

  const std::string rig_path_;
  std::mutex mutex_;  // guards the two below
  std::shared_ptr<const config::RigConfig> rig_;
  std::vector<FileIdentity> files_;  // what rig_ was loaded from
};

}  // namespace photorig::daemon
