// The daemon's own cost per frame, device time excluded: for a 1 MP 16-bit
// frame, the step bookkeeping plus the durable write (encode streamed into a
// temp file, rename, journal append, one syncfs), against a bare write + fsync
// of the same bytes in the same run, and the encode alone (no I/O) to split
// CPU from disk. The ratio is the figure to quote; absolute times depend on
// the filesystem's fsync cost.
//   bench_daemon --benchmark_filter=. (scripts/run-benchmarks.sh runs it too)

#include "photorig/daemon/capture/run_store.h"

#include <benchmark/benchmark.h>
#include <fcntl.h>
#include <unistd.h>

#include <filesystem>
#include <random>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
constexpr int kWidth = 1024, kHeight = 1024;

drivers::Frame NoisyFrame() {
  drivers::Frame frame;
  frame.width = kWidth;
  frame.height = kHeight;
  frame.bit_depth = 12;
  frame.exposure_us = 10000;
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 12.0);
  frame.pixels.resize(static_cast<std::size_t>(kWidth) * kHeight);
  for (int y = 0; y < kHeight; ++y)
    for (int x = 0; x < kWidth; ++x)
      frame.pixels[static_cast<std::size_t>(y) * kWidth + x] =
          static_cast<std::uint16_t>(std::clamp(64 + 1500.0 * (x + y) / (kWidth + kHeight) + noise(rng), 0.0, 4095.0));
  return frame;
}

fs::path ScratchDir(const char* name) {
  const fs::path dir = fs::temp_directory_path() / (std::string("photorig-bench-") + name + "-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

void BM_BareWriteFsync(benchmark::State& state) {
  const drivers::Frame frame = NoisyFrame();
  const fs::path dir = ScratchDir("bare");
  fs::create_directories(dir);
  const std::size_t bytes = frame.pixels.size() * sizeof(std::uint16_t);
  int i = 0;
  for (auto _ : state) {
    fs::path path = dir / "f";
    path += std::to_string(i++ % 64);
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (::write(fd, frame.pixels.data(), bytes) != static_cast<ssize_t>(bytes)) state.SkipWithError("write failed");
    ::fsync(fd);
    ::close(fd);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes));
  fs::remove_all(dir);
}
BENCHMARK(BM_BareWriteFsync)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_EncodeFrame(benchmark::State& state) {
  const drivers::Frame frame = NoisyFrame();
  Png16Encoder encoder;
  std::size_t bytes = 0;
  for (auto _ : state)
    benchmark::DoNotOptimize(encoder.Encode(frame.pixels.data(), kWidth, kHeight,
                                            [&](const std::uint8_t*, std::size_t size) { bytes += size; }));
  benchmark::DoNotOptimize(bytes);
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * frame.pixels.size() * 2));
}
BENCHMARK(BM_EncodeFrame)->Unit(benchmark::kMillisecond)->UseRealTime();

// One step's worth of daemon work on a frame the camera already delivered.
void BM_DaemonFrame(benchmark::State& state) {
  const drivers::Frame frame = NoisyFrame();
  const fs::path dir = ScratchDir("daemon");
  RunManifest header;
  header.width = kWidth;
  header.height = kHeight;
  header.bit_depth = 12;
  auto writer = std::make_unique<RunWriter>(dir.string(), header);
  config::CaptureStep step;
  step.kind = config::CaptureStep::Kind::kDark;
  step.pattern = std::make_shared<const drivers::LightPattern>(drivers::LightPattern::AllOff(48));
  step.exposure_us = 10000;
  int index = 0;
  for (auto _ : state) {
    step.index = index;
    step.label = "frame" + std::to_string(index++);
    if (writer->HasFrame(step.index)) state.SkipWithError("checkpoint lookup is wrong");
    benchmark::DoNotOptimize(writer->WriteFrame(step, frame));
    if (index % 64 == 0) {  // keep the run (and the checkpoint list) bounded
      state.PauseTiming();
      writer.reset();
      fs::remove_all(dir);
      writer = std::make_unique<RunWriter>(dir.string(), header);
      index = 0;
      state.ResumeTiming();
    }
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * frame.pixels.size() * 2));
  writer.reset();
  fs::remove_all(dir);
}
BENCHMARK(BM_DaemonFrame)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace photorig::daemon

BENCHMARK_MAIN();
