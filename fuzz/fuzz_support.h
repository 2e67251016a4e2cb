#pragma once
// What the fuzz targets share: a private temporary directory per process and
// file writing. A target calls the parser as the program does and catches only
// the errors the parser documents; anything else (a crash, a sanitizer report,
// another exception escaping, a hang) is what the fuzzer is there to find.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <system_error>

namespace photorig::fuzz {

// Created on first use, removed at exit. In /dev/shm where there is one: the
// targets write files for every input, and the run store's go through
// fdatasync, which on a disk waits for the disk every time. The path is never
// destroyed: a static object would be destroyed before the exit handler
// registered while constructing it runs, leaving the directory behind.
inline const std::filesystem::path& WorkDir() {
  static const std::filesystem::path* dir = [] {
    const std::filesystem::path shm = "/dev/shm";
    const std::filesystem::path parent =
        std::filesystem::is_directory(shm) ? shm : std::filesystem::temp_directory_path();
    std::string pattern = (parent / "photorig-fuzz-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) std::abort();
    std::atexit([] {
      std::error_code ignored;
      std::filesystem::remove_all(WorkDir(), ignored);
    });
    return new std::filesystem::path(pattern);
  }();
  return *dir;
}

inline void WriteBytes(const std::filesystem::path& path, const std::uint8_t* data, std::size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out) std::abort();  // the harness's own failure, not the parser's
}

inline std::string ReadBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void WriteText(const std::filesystem::path& path, const std::string& text) {
  WriteBytes(path, reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
}

// Seeds: when PHOTORIG_FUZZ_SEEDS names a directory, a target writes the valid
// inputs it starts from there (`scripts/fuzz.sh seeds` writes fuzz/corpus/
// this way, so the seeds follow the formats as they change). For a target
// whose input is a selector byte and a file's bytes, each file is prefixed by
// the byte that selects it.
inline void WriteSeed(const std::string& name, const std::string& input) {
  const char* dir = std::getenv("PHOTORIG_FUZZ_SEEDS");
  if (dir == nullptr) return;
  WriteText(std::filesystem::path(dir) / name, input);
}

inline void WriteSeed(const std::string& name, std::uint8_t selector, const std::string& bytes) {
  WriteSeed(name, std::string(1, static_cast<char>(selector)) + bytes);
}

// A file of the source tree (config/rigs/..., the fixed rig the recipe and API targets use).
inline std::string SourcePath(const std::string& relative) { return std::string(PHOTORIG_SOURCE_DIR) + "/" + relative; }

}  // namespace photorig::fuzz
