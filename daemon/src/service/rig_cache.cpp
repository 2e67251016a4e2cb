#include "photorig/daemon/service/rig_cache.h"

namespace photorig::daemon {
namespace fs = std::filesystem;

std::optional<RigFileCache::FileIdentity> RigFileCache::IdentityOf(const std::string& path) {
  std::error_code error;
  const fs::file_time_type modified = fs::last_write_time(path, error);
  if (error) return std::nullopt;
  const std::uintmax_t size_bytes = fs::file_size(path, error);
  if (error) return std::nullopt;
  return FileIdentity{path, modified, size_bytes};
}

std::shared_ptr<const config::RigConfig> RigFileCache::Get() {
  std::lock_guard lock(mutex_);
  bool unchanged = rig_ != nullptr;
  for (auto file = files_.begin(); unchanged && file != files_.end(); ++file) {
    const std::optional<FileIdentity> now = IdentityOf(file->path);
    unchanged = now && now->modified == file->modified && now->size_bytes == file->size_bytes;
  }
  if (unchanged) return rig_;

  rig_.reset();
  files_.clear();
  // Looked at before loading, so that a file written in between is loaded again next time.
  const std::optional<FileIdentity> rig_file = IdentityOf(rig_path_);
  auto rig = std::make_shared<const config::RigConfig>(config::LoadRigConfig(rig_path_));
  std::optional<FileIdentity> model_file;
  if (rig->camera.color_model) model_file = IdentityOf(rig->camera.color_model->path);
  // A file that could not be looked at leaves nothing to compare with: not kept, loaded at every call.
  if (!rig_file || (rig->camera.color_model && !model_file)) return rig;
  files_.push_back(*rig_file);
  if (model_file) files_.push_back(*model_file);
  rig_ = rig;
  return rig;
}

}  // namespace photorig::daemon
