#include "photorig/daemon/io/image_io.h"
#include "photorig/daemon/io/png16.h"
#include "photorig/daemon/capture/run_store.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <zlib.h>

#include <filesystem>
#include <fstream>
#include <random>

namespace photorig::daemon {
namespace {

using photorig::testing::TempDir;

TEST(ImageIo, FloatTiffRoundTripsBitExactly) {
  TempDir dir;
  std::mt19937 rng(1);
  std::normal_distribution<float> value(0.0f, 3.0f);
  cv::Mat normals(37, 53, CV_32FC3), scalar(37, 53, CV_32F);
  for (auto& v : cv::Mat_<cv::Vec3f>(normals)) v = cv::Vec3f(value(rng), value(rng), value(rng));
  for (auto& v : cv::Mat_<float>(scalar)) v = value(rng);
  normals.at<cv::Vec3f>(0, 0) = cv::Vec3f(NAN, NAN, NAN);
  const std::string n_path = (dir.path() / "n.tiff").string(), s_path = (dir.path() / "s.tiff").string();
  WriteFloatTiff(n_path, normals);
  WriteFloatTiff(s_path, scalar);
  cv::Mat n_back = ReadFloatTiff(n_path);
  const cv::Mat s_back = ReadFloatTiff(s_path);
  ASSERT_EQ(n_back.type(), CV_32FC3);
  EXPECT_TRUE(std::isnan(n_back.at<cv::Vec3f>(0, 0)[0]));
  normals.at<cv::Vec3f>(0, 0) = n_back.at<cv::Vec3f>(0, 0) = cv::Vec3f(0, 0, 0);
  EXPECT_EQ(cv::norm(normals, n_back, cv::NORM_INF), 0.0);  // x stays x: channel order preserved
  EXPECT_EQ(cv::norm(scalar, s_back, cv::NORM_INF), 0.0);
  // In the file, the first channel (R) is x, as other tools expect.
  const cv::Mat raw = cv::imread(n_path, cv::IMREAD_UNCHANGED);
  EXPECT_EQ(raw.at<cv::Vec3f>(5, 5)[2], normals.at<cv::Vec3f>(5, 5)[0]);
}

TEST(ImageIo, DurableWriteLeavesNoTempFile) {
  TempDir dir;
  const std::string path = (dir.path() / "a.txt").string();
  WriteFileDurably(path, std::string("hello"));
  EXPECT_EQ(photorig::testing::ReadText(path), "hello");
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
}

// What OpenCV would hand to its DICOM decoder, which aborts the process on a
// malformed file: DICOM's mark at byte 128 (a fuzzer's find, as the DiLiGenT
// reader met it), and a PNG whose bytes there were overwritten with it.
TEST(ImageIo, AFileMarkedAsDicomIsRefusedNamingItAndTheProcessLives) {
  TempDir dir;
  const std::string marked = (dir.path() / "001.png").string(), png = (dir.path() / "002.png").string();
  {
    std::ofstream out(marked, std::ios::binary);
    out << "\xce 2 1\n" << std::string(114, '\xca') << "0.92.1 0\nDICM1\n";
  }
  try {
    ReadImage(marked);
    ADD_FAILURE() << "read a file whose first bytes name no image format";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(marked), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not a PNG, TIFF"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ReadInputImage(marked), std::invalid_argument);  // a request's file: the request's fault

  cv::Mat pixels(40, 40, CV_16UC3);
  cv::randu(pixels, 0, 65535);
  ASSERT_TRUE(cv::imwrite(png, pixels));
  const cv::Mat back = ReadImage(png);
  ASSERT_EQ(back.type(), CV_16UC3);
  EXPECT_EQ(cv::norm(pixels, back, cv::NORM_INF), 0.0);  // unchanged: 16 bits, every channel
  EXPECT_EQ(ReadImage(png, solvers::codecs::ReadMode::kGrey).type(), CV_16UC1);  // grey at the stored depth
  {
    std::fstream patch(png, std::ios::binary | std::ios::in | std::ios::out);
    patch.seekp(128);
    patch.write("DICM", 4);
  }
  EXPECT_THROW(ReadImage(png), std::runtime_error);  // its PNG decoder fails; no other decoder is tried
  EXPECT_THROW(ReadImage(dir.path().string()), std::runtime_error);  // a directory
  {
    // A sparse file past 1 GiB that starts as a PNG is refused before it is read into memory.
    const std::filesystem::path huge = dir.path() / "huge.png";
    std::ofstream(huge, std::ios::binary) << "\x89PNG\r\n\x1a\n";
    std::filesystem::resize_file(huge, (std::uintmax_t{1} << 30) + 1);
    std::string why;
    EXPECT_TRUE(TryReadImage(huge.string(), solvers::codecs::ReadMode::kAsStored, &why).empty());
    EXPECT_EQ(why, "larger than 1 GiB");
  }
  EXPECT_THROW(ReadImage((dir.path() / "absent.png").string()), std::runtime_error);
}

drivers::Frame MakeFrame(int width, int height, std::uint64_t id) {
  drivers::Frame frame;
  frame.width = width;
  frame.height = height;
  frame.bit_depth = 12;
  frame.frame_id = id;
  frame.exposure_us = 1000;
  for (int i = 0; i < width * height; ++i) frame.pixels.push_back(static_cast<std::uint16_t>((i * 37 + id) % 4096));
  return frame;
}

RunManifest Header() {
  RunManifest header;
  header.run_id = "t";
  header.width = 20;
  header.height = 10;
  header.bit_depth = 12;
  header.lights.resize(1);  // one LED straight above: id 0, unit intensity
  return header;
}

config::CaptureStep Step(int index, int led) {
  config::CaptureStep step;
  step.index = index;
  step.kind = led < 0 ? config::CaptureStep::Kind::kDark : config::CaptureStep::Kind::kLight;
  step.led = led;
  step.label = "000" + std::to_string(index) + (led < 0 ? "_dark" : "_led00");
  step.pattern = std::make_shared<const drivers::LightPattern>(led < 0 ? drivers::LightPattern::AllOff(1)
                                                                 : drivers::LightPattern::Single(1, 0, 0.5));
  return step;
}

// Shapes chosen to put stored-block boundaries inside a sample, on a filter
// byte and at the end of a row, and to make a single block and many. The file
// is what arrives at the sink, in bounded pieces (what RunWriter writes as it
// encodes), decoded by OpenCV's own PNG reader.
TEST(Png16Encoder, EveryShapeDecodesBitExactWithMatchingChecksum) {
  Png16Encoder encoder;  // one encoder for all: its buffer is reused
  std::mt19937 rng(3);
  for (const auto& [width, height] : std::vector<std::pair<int, int>>{
           {1, 1}, {3, 2}, {32767, 1}, {32767, 3}, {777, 333}, {40000, 3}, {5, 70000}, {1024, 1024}}) {
    std::vector<std::uint16_t> pixels(static_cast<std::size_t>(width) * height);
    for (auto& p : pixels) p = static_cast<std::uint16_t>(rng());
    std::vector<std::uint8_t> file;
    const std::uint32_t crc = encoder.Encode(pixels.data(), width, height, [&](const std::uint8_t* data, std::size_t size) {
      EXPECT_LE(size, Png16Encoder::kPieceBytes);
      file.insert(file.end(), data, data + size);
    });
    const cv::Mat decoded = cv::imdecode(cv::Mat(1, static_cast<int>(file.size()), CV_8U, file.data()), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(decoded.empty()) << width << "x" << height;
    ASSERT_EQ(decoded.type(), CV_16U);
    ASSERT_EQ(decoded.size(), cv::Size(width, height));
    EXPECT_TRUE(std::equal(pixels.begin(), pixels.end(), decoded.ptr<std::uint16_t>(0))) << width << "x" << height;
    EXPECT_EQ(crc, ::crc32(0L, reinterpret_cast<const Bytef*>(pixels.data()),
                           static_cast<uInt>(pixels.size() * sizeof(std::uint16_t))));
  }
}

TEST(RunStore, FramesLandOnDiskBitExactWithJournalAndManifest) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  {
    RunWriter writer(run, Header());
    writer.WriteFrame(Step(0, -1), MakeFrame(20, 10, 0));
    writer.WriteFrame(Step(1, 0), MakeFrame(20, 10, 1));
    // The journal holds the frame before the writer moves on.
    std::ifstream journal(std::filesystem::path(run) / "journal.jsonl");
    std::string line;
    int lines = 0;
    while (std::getline(journal, line)) ++lines;
    EXPECT_EQ(lines, 3);  // header + 2 frames
    writer.Finish({CaptureStatus::kComplete, "", 0, 0, 0, 0});
  }
  const RunManifest manifest = LoadRunManifest(run);
  EXPECT_EQ(manifest.status, CaptureStatus::kComplete);
  ASSERT_EQ(manifest.frames.size(), 2u);
  EXPECT_EQ(manifest.frames[1].level, 0.5);
  EXPECT_EQ(manifest.frames[1].kind, config::CaptureStep::Kind::kLight);
  const cv::Mat image = LoadFrame(run, manifest.frames[1]);
  const drivers::Frame expected = MakeFrame(20, 10, 1);
  for (int i = 0; i < 200; ++i) ASSERT_EQ(image.ptr<std::uint16_t>()[i], expected.pixels[i]);
}

// The status words are the run format's: runs stored before the status was
// typed must read back, and new runs must write the same words.
TEST(RunStore, CaptureStatusIsStoredAsTheFormatsWords) {
  const std::pair<CaptureStatus, const char*> words[] = {{CaptureStatus::kRunning, "running"},
                                                          {CaptureStatus::kComplete, "complete"},
                                                          {CaptureStatus::kFailed, "failed"},
                                                          {CaptureStatus::kAborted, "aborted"},
                                                          {CaptureStatus::kInterrupted, "interrupted"}};
  for (const auto& [status, word] : words) {
    EXPECT_STREQ(CaptureStatusName(status), word);
    EXPECT_EQ(CaptureStatusFromName(word), status) << word;
    const StopRecord stop{status, "why", 3, 4, 1, 2};
    EXPECT_EQ(ToJson(stop)["status"], word);
    EXPECT_EQ(StopRecordFromJson(ToJson(stop)).status, status) << word;
  }
  EXPECT_EQ(CaptureStatusFromName("done"), std::nullopt);  // a queue state, not a capture status

  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  {
    RunWriter writer(run, Header());
    writer.Finish({CaptureStatus::kAborted, "stop requested", 0, 2, 0, 0});
  }
  const nlohmann::json stored = nlohmann::json::parse(std::ifstream(std::filesystem::path(run) / "manifest.json"));
  EXPECT_EQ(stored["status"], "aborted");
  EXPECT_EQ(stored["stop"]["status"], "aborted");
  // A word the format does not have is a corrupt manifest, named as such.
  nlohmann::json tampered = stored;
  tampered["status"] = "finished";
  std::ofstream(std::filesystem::path(run) / "manifest.json") << tampered.dump();
  try {
    LoadRunManifest(run);
    ADD_FAILURE() << "an unknown status loaded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("unknown capture status 'finished'"), std::string::npos) << e.what();
  }
}

// A number where the format has an integer, with a fraction or beyond its
// type's range, is refused naming the field (it once reached a conversion
// with undefined behaviour: found by fuzz_manifest).
// A finished run of one lit frame in `run`: its manifest's path and contents.
std::pair<std::filesystem::path, nlohmann::json> OneFrameRun(const std::string& run) {
  {
    RunWriter writer(run, Header());
    writer.WriteFrame(Step(1, 0), MakeFrame(20, 10, 1));
    writer.Finish({CaptureStatus::kComplete, "", 1, 1, 0, 0});
  }
  const std::filesystem::path file = std::filesystem::path(run) / "manifest.json";
  return {file, nlohmann::json::parse(std::ifstream(file))};
}

TEST(RunStore, IntegerFieldsWithAFractionOrOutOfRangeAreRefusedNamingTheField) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  const auto [file, stored] = OneFrameRun(run);
  ASSERT_EQ(LoadRunManifest(run).frames.size(), 1u);
  const std::vector<std::pair<nlohmann::json::json_pointer, nlohmann::json>> tampering = {
      {nlohmann::json::json_pointer("/camera/width"), 1.79596e137},
      {nlohmann::json::json_pointer("/frames/0/led"), 2.5},
      {nlohmann::json::json_pointer("/frames/0/crc32"), 8589934592LL},  // 2^33: not a CRC-32
      {nlohmann::json::json_pointer("/frames/0/host_timestamp_ns"), -1e300}};
  for (const auto& [where, value] : tampering) {
    nlohmann::json tampered = stored;
    tampered[where] = value;
    std::ofstream(file) << tampered.dump();
    const std::string field = where.back();
    try {
      LoadRunManifest(run);
      ADD_FAILURE() << field << " = " << value.dump() << " loaded";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("'" + field + "' must be an integer"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("manifest.json: corrupt manifest"), std::string::npos) << e.what();
    }
  }
}

// A value no camera, LED or capture step can have is a corrupt manifest,
// named with its field and where it is, before any solver sees it (a width
// of -5 once ended in an OpenCV assertion that named no file).
TEST(RunStore, FieldsOutsideTheirRangeAreRefusedNamingTheFieldAndWhere) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  const auto [file, stored] = OneFrameRun(run);
  ASSERT_EQ(LoadRunManifest(run).frames.size(), 1u);
  struct Tampering {
    const char* pointer;
    nlohmann::json value;
    const char* message;  // what the error must say
  };
  const Tampering tampering[] = {
      {"/camera/width", -5, "'width' must be an integer from 1 to 65535, not -5"},
      {"/camera/height", 0, "'height' must be an integer from 1 to 65535"},
      {"/camera/bit_depth", 0, "'bit_depth' must be an integer from 1 to 16"},
      {"/camera/bit_depth", 99, "'bit_depth' must be an integer from 1 to 16, not 99"},
      {"/camera/pixel_pitch_mm", -0.1, "'pixel_pitch_mm' must be a finite number >= 0, not -0.1"},
      {"/camera/saturation_dn", 70000, "'saturation_dn' must be a finite number from 0 to 65535"},
      {"/camera/dn_per_radiance_per_us", "fast", "'dn_per_radiance_per_us' must be a finite number >= 0"},
      {"/lights/0/direction", nlohmann::json::array({0, 0, 0}), "light 0: 'direction' must be three finite numbers not all zero"},
      {"/lights/0/direction", nlohmann::json::array({0, 1}), "light 0: 'direction' must be three finite numbers"},
      {"/lights/0/intensity", -1, "light 0: 'intensity' must be a finite number >= 0"},
      {"/lights/0/id", -3, "light 0: 'id' must be an integer from 0"},
      {"/frames/0/led", -3, "frame 0: 'led' must be an integer from -1"},
      {"/frames/0/led", 7, "names LED 7 but the run has 1 lights"},
      {"/frames/0/level", 1.5, "frame 0: 'level' must be a finite number from 0 to 1, not 1.5"},
      {"/frames/0/exposure_us", -10, "frame 0: 'exposure_us' must be a finite number >= 0"},
      {"/frames/0/bit_depth", 0, "frame 0: 'bit_depth' must be an integer from 1 to 16"},
      {"/frames/0/index", -1, "frame 0: 'index' must be an integer from 0"},
      {"/stop/frames", -2, "'frames' must be an integer from 0"},
  };
  for (const Tampering& t : tampering) {
    nlohmann::json tampered = stored;
    tampered[nlohmann::json::json_pointer(t.pointer)] = t.value;
    std::ofstream(file) << tampered.dump();
    try {
      LoadRunManifest(run);
      ADD_FAILURE() << t.pointer << " = " << t.value.dump() << " loaded";
    } catch (const DamagedRunError& e) {
      EXPECT_NE(std::string(e.what()).find(t.message), std::string::npos) << t.pointer << ": " << e.what();
      EXPECT_NE(std::string(e.what()).find("manifest.json: corrupt manifest"), std::string::npos) << e.what();
    }
  }
  // A value at the edge of its range is a value, not corruption.
  nlohmann::json edge = stored;
  edge["frames"][0]["led"] = 0;
  edge["frames"][0]["level"] = 1.0;
  edge["camera"]["pixel_pitch_mm"] = 0.0;  // unknown
  std::ofstream(file) << edge.dump();
  EXPECT_EQ(LoadRunManifest(run).frames[0].led, 0);
}

TEST(RunStore, CorruptFrameIsDetectedByItsChecksum) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  RunWriter writer(run, Header());
  const FrameRecord record = writer.WriteFrame(Step(1, 0), MakeFrame(20, 10, 1));
  // Replace the frame with a valid PNG holding different pixels.
  drivers::Frame other = MakeFrame(20, 10, 2);
  cv::imwrite((std::filesystem::path(run) / record.file).string(), cv::Mat(10, 20, CV_16U, other.pixels.data()));
  EXPECT_THROW(
      {
        try {
          LoadFrame(run, record);
        } catch (const std::runtime_error& e) {
          EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos);
          throw;
        }
      },
      std::runtime_error);
  // A truncated file is named in the error.
  std::filesystem::resize_file(std::filesystem::path(run) / record.file, 20);
  try {
    LoadFrame(run, record);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(record.file), std::string::npos) << e.what();
  }
}

// A manifest names frames inside its run: one elsewhere is refused unread.
TEST(RunStore, AFrameOutsideTheRunIsRefusedUnread) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  RunWriter writer(run, Header());
  FrameRecord record = writer.WriteFrame(Step(1, 0), MakeFrame(20, 10, 1));
  for (const std::string& outside : std::vector<std::string>{"/etc/passwd", "../run/" + record.file, "frames/../../x.png"}) {
    record.file = outside;
    try {
      LoadFrame(run, record);
      ADD_FAILURE() << outside << " was read";
    } catch (const DamagedRunError& e) {
      EXPECT_NE(std::string(e.what()).find("'" + outside + "' lies outside the run's folder"), std::string::npos)
          << e.what();
    }
  }
}

TEST(RunStore, ShortFramesAreRefusedAndExistingRunsAreNotOverwritten) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  RunWriter writer(run, Header());
  drivers::Frame short_frame = MakeFrame(20, 10, 0);
  short_frame.pixels.resize(150);
  EXPECT_THROW(writer.WriteFrame(Step(0, -1), short_frame), std::runtime_error);
  EXPECT_THROW(RunWriter(run, Header()), std::runtime_error);
}

TEST(RunStore, CorruptManifestIsNamed) {
  TempDir dir;
  dir.Write("run/manifest.json", "{\"format\": \"photorig-run/1\", \"run_id\": ");
  try {
    LoadRunManifest((dir.path() / "run").string());
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("manifest.json: corrupt manifest"), std::string::npos) << e.what();
  }
}

TEST(RunStore, ReopenRepairsWhatACrashLeavesAndKeepsEveryGoodFrameOnce) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  {
    RunWriter writer(run, Header());
    for (int i = 0; i < 4; ++i) writer.WriteFrame(Step(i, i == 0 ? -1 : 0), MakeFrame(20, 10, i));
  }
  namespace fs = std::filesystem;
  // What a kill -9 can leave: a temp file, a frame renamed into place whose
  // journal line never landed, a torn last journal line; and a frame damaged since.
  std::ofstream(fs::path(run) / "frames" / "0004_led00.png.tmp") << "partial";
  fs::copy_file(fs::path(run) / "frames" / "0001_led00.png", fs::path(run) / "frames" / "0005_led00.png");
  std::ofstream(fs::path(run) / "journal.jsonl", std::ios::app) << "{\"index\": 6, \"fi";
  {
    std::fstream damaged(fs::path(run) / "frames" / "0002_led00.png", std::ios::in | std::ios::out | std::ios::binary);
    damaged.seekp(static_cast<std::streamoff>(fs::file_size(fs::path(run) / "frames" / "0002_led00.png") / 2));
    damaged.write("XXXXXXXXXXXX", 12);
  }

  RecoveryReport recovery;
  auto writer = RunWriter::Reopen(run, &recovery);
  EXPECT_TRUE(recovery.journal_tail_torn);
  EXPECT_EQ(recovery.frames_kept, 3);
  EXPECT_EQ(recovery.frames_discarded, 1);
  EXPECT_EQ(recovery.removed_files.size(), 3u);  // the temp file, the unjournalled frame, the damaged frame
  EXPECT_TRUE(writer->HasFrame(0) && writer->HasFrame(1) && writer->HasFrame(3));
  EXPECT_FALSE(writer->HasFrame(2));
  // The retaken step lands once; the finished run verifies clean.
  writer->WriteFrame(Step(2, 0), MakeFrame(20, 10, 2));
  writer->Finish({CaptureStatus::kComplete, "", 0, 4, 0, 0});
  EXPECT_TRUE(VerifyRun(run).empty()) << VerifyRun(run).front();
  const RunManifest manifest = LoadRunManifest(run);
  ASSERT_EQ(manifest.frames.size(), 4u);
  ASSERT_TRUE(manifest.stop.has_value());
  EXPECT_EQ(manifest.stop->frames, 4);
  // A second reopen of a clean run changes nothing.
  RecoveryReport again;
  RunWriter::Reopen(run, &again);
  EXPECT_EQ(again.frames_kept, 4);
  EXPECT_FALSE(again.journal_tail_torn);
  EXPECT_TRUE(again.removed_files.empty());
}

TEST(RunStore, VerifyRunFindsMissingAndStrayFrames) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  RunWriter writer(run, Header());
  writer.WriteFrame(Step(0, -1), MakeFrame(20, 10, 0));
  writer.Finish({CaptureStatus::kComplete, "", 0, 2, 0, 0});
  std::ofstream(std::filesystem::path(run) / "frames" / "stray.png") << "x";
  const auto problems = VerifyRun(run);
  ASSERT_EQ(problems.size(), 2u);
  EXPECT_NE(problems[0].find("step 1 missing"), std::string::npos) << problems[0];
  EXPECT_NE(problems[1].find("stray.png"), std::string::npos) << problems[1];
}

}  // namespace
TEST(RunStore, ReopenNamesAJournalLineThatIsNotARecord) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  {
    RunWriter writer(run, Header());
    writer.WriteFrame(Step(0, -1), MakeFrame(20, 10, 0));
  }
  // Valid JSON, but not a frame record: a number, then (separately) a header that is not an object.
  for (const std::string bad : {"7\n", "{\"run\": 3}\n", "{\"index\": \"one\", \"file\": 2}\n"}) {
    const std::filesystem::path journal = std::filesystem::path(run) / "journal.jsonl";
    const std::string good = photorig::testing::ReadText(journal);
    std::ofstream(journal, std::ios::app) << bad;
    try {
      RunWriter::Reopen(run, nullptr);
      ADD_FAILURE() << "accepted " << bad;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("journal.jsonl:3: corrupt line"), std::string::npos) << e.what();
    }
    std::ofstream(journal, std::ios::trunc) << good;
  }
}

TEST(RunStore, VerifyRunOfAHugeStepCountNamesAFewMissingStepsAndCountsTheRest) {
  TempDir dir;
  const std::string run = (dir.path() / "run").string();
  RunWriter writer(run, Header());
  writer.WriteFrame(Step(0, -1), MakeFrame(20, 10, 0));
  writer.Finish({CaptureStatus::kComplete, "", 1, 2147483647, 0, 0});
  const auto problems = VerifyRun(run);
  ASSERT_EQ(problems.size(), 21u);
  EXPECT_NE(problems[0].find("step 1 missing"), std::string::npos) << problems[0];
  EXPECT_NE(problems[19].find("step 20 missing"), std::string::npos) << problems[19];
  EXPECT_EQ(problems[20], "2147483626 more steps missing");
}

}  // namespace photorig::daemon
