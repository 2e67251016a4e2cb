#pragma once
// Temporary directories and files for tests, removed when the test ends;
// the photorig and photorigd executables run as a test runs them.

#include <gtest/gtest.h>

#include <cstdlib>
#include <csignal>
#include <cstdio>
#include <sys/wait.h>
#include <unistd.h>
#include <filesystem>
#include <chrono>
#include <fstream>
#include <regex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace photorig::testing {

class TempDir {
 public:
  TempDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "photorig-test-XXXXXX").string();
    path_ = ::mkdtemp(pattern.data());
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  const std::filesystem::path& path() const { return path_; }
  std::string Write(const std::string& name, const std::string& text) const {
    const auto file = path_ / name;
    std::filesystem::create_directories(file.parent_path());
    std::ofstream(file) << text;
    return file.string();
  }

 private:
  std::filesystem::path path_;
};

inline std::string SourceDir() {
  const char* dir = std::getenv("PHOTORIG_SOURCE_DIR");
  return dir ? dir : ".";
}

inline std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// A small simulated dome (4 LEDs, 32x32 camera) for fast runs; `faults` is
// the body of sim.faults (YAML flow map), empty for none.
inline std::string SmallRigYaml(const std::string& faults = "", int leds = 4) {
  std::string text =
      "rig: {name: small-dome}\n"
      "lights:\n  driver: sim\n  id: small-dome\n  leds:\n";
  for (int i = 0; i < leds; ++i)
    text += "    - {id: " + std::to_string(i) + ", direction: [" + std::to_string(0.5 * ((i % 2) ? 1 : -1)) + ", " +
            std::to_string(0.5 * ((i / 2 % 2) ? 1 : -1)) + ", 0.707107]}\n";
  text +=
      "camera: {driver: sim, id: small-cam, width: 32, height: 32, pixel_pitch_mm: 1.0, bit_depth: 12, "
      "exposure_us: 1000}\n"
      "sim:\n  seed: 7\n  scene: {shape: sphere, radius_mm: 12}\n";
  if (!faults.empty()) text += "  faults: " + faults + "\n";
  return text;
}

// One dark frame and one frame per LED.
inline std::string SmallRecipeYaml(const std::string& rig_path = "", int darks = 1) {
  std::string text = "recipe:\n  name: small\n";
  if (!rig_path.empty()) text += "  rig: " + rig_path + "\n";
  text += "capture:\n  exposure_us: 1000\n  steps:\n    - dark: {count: " + std::to_string(darks) +
          "}\n    - each_led: {leds: all}\n";
  return text;
}

// A shipped simulated rig as built, not as drawn: `errors` (lines of its
// `sim:` section, e.g. "led_direction_error_deg: 1.5") written into a copy in
// `dir`, whose path is returned; the file states the rig as drawn, so what a
// calibration finds is hidden from everything but the frames.
inline std::filesystem::path AsBuiltRig(const std::filesystem::path& dir, const std::string& shipped_rig,
                                        const std::vector<std::string>& errors) {
  const std::string drawing = ReadText(SourceDir() + "/config/rigs/" + shipped_rig);
  std::string lines;
  for (const std::string& error : errors) lines += "  " + error + "\n";
  const std::string as_built = std::regex_replace(drawing, std::regex("\nsim:\n"), "\nsim:\n" + lines);
  if (as_built == drawing) throw std::runtime_error(shipped_rig + " has no sim: section to put errors in");
  const std::filesystem::path rig = dir / "as-built.yaml";
  std::ofstream(rig) << as_built;
  return rig;
}

// A simulated rig's YAML with photon and read noise switched off.
inline std::string NoiseFreeRig(std::string rig) {
  rig = std::regex_replace(rig, std::regex("read_noise_e: [0-9.]+"), "read_noise_e: 0");
  return std::regex_replace(rig, std::regex("shot_noise: true"), "shot_noise: false");
}

#ifdef PHOTORIG_BIN_DIR
// Runs build/bin/photorig with `arguments`, output to `log`; returns its exit code.
inline int RunPhotorig(const std::string& arguments, const std::filesystem::path& log) {
  const std::string command =
      std::string(PHOTORIG_BIN_DIR) + "/photorig " + arguments + " > " + log.string() + " 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

struct CommandOutcome {
  int exit_code = -1;
  std::string out, err;
};

// Runs build/bin/photorig with `arguments`, stdout and stderr kept apart
// (files in `dir`, so a --json document can be parsed on its own).
inline CommandOutcome Photorig(const std::string& arguments, const TempDir& dir) {
  static int calls = 0;
  const std::filesystem::path out = dir.path() / ("out" + std::to_string(calls)),
                              err = dir.path() / ("err" + std::to_string(calls));
  ++calls;
  const std::string command = std::string(PHOTORIG_BIN_DIR) + "/photorig " + arguments + " > " + out.string() +
                              " 2> " + err.string() + " < /dev/null";
  const int status = std::system(command.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ReadText(out), ReadText(err)};
}

// photorigd on any free port, for as long as the object lives.
class Daemon {
 public:
  Daemon(const std::filesystem::path& data_root, const std::string& rig, const std::filesystem::path& log) : log_(log) {
    pid_ = ::fork();
    if (pid_ == 0) {
      const std::string bin = std::string(PHOTORIG_BIN_DIR) + "/photorigd";
      if (!std::freopen(log.c_str(), "a", stdout) || !std::freopen(log.c_str(), "a", stderr)) _exit(126);
      ::execl(bin.c_str(), bin.c_str(), "--data-root", data_root.c_str(), "--rig", rig.c_str(), "--port", "0",
              static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  ~Daemon() {
    ::kill(pid_, SIGTERM);
    ::waitpid(pid_, nullptr, 0);
  }
  // The address from its "event=ready" line, or "" if it never got ready.
  std::string WaitReady() const {
    static const std::regex ready(R"(event=ready listen=(127\.0\.0\.1:\d+))");
    for (int i = 0; i < 1000; ++i) {
      std::smatch match;
      const std::string text = ReadText(log_);
      if (std::regex_search(text, match, ready)) return "http://" + match[1].str();
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return "";
  }

 private:
  std::filesystem::path log_;
  pid_t pid_ = -1;
};
#endif

}  // namespace photorig::testing
