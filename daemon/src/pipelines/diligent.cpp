#include "photorig/daemon/pipelines/diligent.h"

#include "photorig/daemon/io/image_io.h"
#include "photorig/config/rig.h"
#include "photorig/config/sim.h"
#include "photorig/config/yaml_node.h"

#include <matio.h>
#include <opencv2/imgproc.hpp>

#include <array>
#include <exception>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace photorig::daemon {
namespace fs = std::filesystem;
namespace {

// Every malformed file is a ConfigError naming the file (and line): bad input
// the user fixes, not a fault of the solve.
[[noreturn]] void Malformed(const fs::path& file, int line, const std::string& message) {
  throw config::ConfigError(file.string(), line, line > 0 ? 1 : 0, "", message);
}

// An image of the folder, unchanged (16-bit stays 16-bit); one that does not
// decode is malformed input like any other file of the folder.
cv::Mat ReadFolderImage(const fs::path& file) {
  std::string why;
  cv::Mat image = TryReadImage(file.string(), solvers::codecs::ReadMode::kAsStored, &why);
  if (image.empty()) Malformed(file, 0, "cannot read as an image (" + why + ")");
  return image;
}

// One image of the folder as the solve takes it (see LoadDiligent): the grey
// frame, channel c scaled by mean(L) / (L_c * channels), and for an RGB image
// the colour frame in R G B, every channel of a pixel with any at the top code
// +inf (clipped). Made in one pass over the decoded pixels, into the stack's
// slabs: splitting, converting and comparing channel by channel made eight
// intermediate images a frame (11 MB of fresh pages for a 612 x 512 colour
// image) and took most of a load.
struct FolderFrame {
  std::string why;              // the file does not decode: why (the rest is empty)
  cv::Size size;
  int depth = 0, channels = 0;  // as decoded
  bool channels_differ = false; // a 3-channel image whose channels differ somewhere (colour, not grey saved as RGB)
};

template <typename T>
void ConvertFolderPixels(const cv::Mat& image, const float* scale, cv::Mat& grey_frame, cv::Mat& rgb_frame,
                         FolderFrame* frame) {
  const int channels = image.channels(), columns = image.cols;
  if (channels != 3) {
    for (int r = 0; r < image.rows; ++r) {
      const T* in = image.ptr<T>(r);
      float* grey = grey_frame.ptr<float>(r);
      for (int x = 0; x < columns; ++x, in += channels) {
        float sum = 0.0f;  // the channels in order, as the sum of per-channel images added
        for (int c = 0; c < channels; ++c) sum += static_cast<float>(in[c]) * scale[c];
        grey[x] = sum;
      }
    }
    return;
  }
  // The top code of the stored depth: 8-bit 255, anything deeper 65535.
  const float full_scale = image.depth() == CV_8U ? 255.0f : 65535.0f;
  const float clipped = std::numeric_limits<float>::infinity();
  bool differ = false;
  for (int r = 0; r < image.rows; ++r) {
    const T* in = image.ptr<T>(r);
    float* grey = grey_frame.ptr<float>(r);
    float* rgb = rgb_frame.ptr<float>(r);
    for (int x = 0; x < columns; ++x, in += 3, rgb += 3) {
      const float b = static_cast<float>(in[0]), g = static_cast<float>(in[1]), red = static_cast<float>(in[2]);
      grey[x] = (b * scale[0] + g * scale[1]) + red * scale[2];  // OpenCV's order: B G R
      differ |= (b != g) | (g != red);
      const bool top = (b >= full_scale) | (g >= full_scale) | (red >= full_scale);
      rgb[0] = top ? clipped : red;
      rgb[1] = top ? clipped : g;
      rgb[2] = top ? clipped : b;
    }
  }
  frame->channels_differ = differ;
}

// Converts the decoded `image` into grey_frame and rgb_frame if it has the
// stack's size, depth and channels (those of `like`, or any when `like` is
// null). intensity: the file's line of light_intensities.txt (R G B).
FolderFrame ConvertFolderFrame(const cv::Mat& image, const cv::Vec3d& intensity, const FolderFrame* like,
                               cv::Mat grey_frame, cv::Mat rgb_frame) {
  FolderFrame frame;
  frame.size = image.size();
  frame.depth = image.depth();
  frame.channels = image.channels();
  if (like && (frame.size != like->size || frame.depth != like->depth || frame.channels != like->channels))
    return frame;  // LoadDiligent refuses it, naming both
  // Colour-balance each channel by its intensity but keep the sensor's scale:
  // grey = mean_c(I_c * mean(L) / L_c), light scale = mean(L). Thresholds in
  // DN (shadows, quantisation) then keep their meaning.
  const double mean_intensity = (intensity[0] + intensity[1] + intensity[2]) / 3.0;
  std::vector<float> scale(frame.channels);
  for (int c = 0; c < frame.channels; ++c) {
    // OpenCV reads BGR; light_intensities.txt lists R G B.
    const double channel_intensity = frame.channels == 3 ? intensity[2 - c] : mean_intensity;
    scale[c] = static_cast<float>(mean_intensity / (channel_intensity * frame.channels));
  }
  switch (image.depth()) {
    case CV_8U: ConvertFolderPixels<std::uint8_t>(image, scale.data(), grey_frame, rgb_frame, &frame); break;
    case CV_16U: ConvertFolderPixels<std::uint16_t>(image, scale.data(), grey_frame, rgb_frame, &frame); break;
    case CV_32F: ConvertFolderPixels<float>(image, scale.data(), grey_frame, rgb_frame, &frame); break;
    default: {  // signed or double data (rare in an image file): through float
      cv::Mat as_float;
      image.convertTo(as_float, CV_32F);
      ConvertFolderPixels<float>(as_float, scale.data(), grey_frame, rgb_frame, &frame);
    }
  }
  return frame;
}

// An image of the folder, unchanged; empty with `why` set if it does not decode.
cv::Mat DecodeFolderImage(const fs::path& file, std::string* why) {
  cv::Mat image = TryReadImage(file.string(), solvers::codecs::ReadMode::kAsStored, why);
  if (image.empty() && why->empty()) *why = "empty image";
  return image;
}

// Decodes `file` and converts it as ConvertFolderFrame does; one that does not
// decode says why in the frame, for LoadDiligent to report in file order.
FolderFrame ReadFolderFrame(const fs::path& file, const cv::Vec3d& intensity, const FolderFrame& like,
                            const cv::Mat& grey_frame, const cv::Mat& rgb_frame) {
  FolderFrame failed;
  const cv::Mat image = DecodeFolderImage(file, &failed.why);
  return image.empty() ? failed : ConvertFolderFrame(image, intensity, &like, grey_frame, rgb_frame);
}

// Non-blank lines with their 1-based line numbers.
std::vector<std::pair<int, std::string>> ReadLines(const fs::path& path) {
  std::error_code error;
  if (fs::is_directory(path, error)) Malformed(path, 0, "is a directory, expected a text file");
  std::ifstream in(path);
  if (!in) Malformed(path, 0, "cannot open (a DiLiGenT folder needs filenames.txt, light_directions.txt and light_intensities.txt)");
  std::vector<std::pair<int, std::string>> lines;
  int number = 0;
  for (std::string line; std::getline(in, line);) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") != std::string::npos) lines.emplace_back(number, line);
  }
  return lines;
}

// Exactly three finite numbers per line, one line per image.
std::vector<std::pair<int, cv::Vec3d>> ReadTriples(const fs::path& path, std::size_t expected) {
  const auto lines = ReadLines(path);
  if (lines.size() != expected)
    Malformed(path, 0, std::to_string(lines.size()) + " lines for " + std::to_string(expected) +
                           " images in filenames.txt: one line per image, in the same order");
  std::vector<std::pair<int, cv::Vec3d>> values;
  for (const auto& [number, text] : lines) {
    std::istringstream fields(text);
    cv::Vec3d v;
    std::string extra;
    if (!(fields >> v[0] >> v[1] >> v[2])) Malformed(path, number, "expected three numbers, got '" + text + "'");
    if (fields >> extra) Malformed(path, number, "expected three numbers, got more ('" + extra + "' after the third)");
    if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]))
      Malformed(path, number, "numbers must be finite");
    values.emplace_back(number, v);
  }
  return values;
}

// DiLiGenT's intensities are of order 1; values far outside this range are a
// unit mistake that would overflow the albedo (1/intensity) in float.
constexpr double kMinLightIntensity = 1e-6, kMaxLightIntensity = 1e6;

// A unit direction towards the light, z towards the camera. Scaled by its
// largest component first so that lengths like 1e308 do not overflow.
Eigen::Vector3d LightDirection(const fs::path& path, int line, const cv::Vec3d& d) {
  const double largest = std::max({std::abs(d[0]), std::abs(d[1]), std::abs(d[2])});
  if (!(largest > 0)) Malformed(path, line, "zero direction");
  const Eigen::Vector3d w = Eigen::Vector3d(d[0], d[1], d[2]) / largest;
  const Eigen::Vector3d unit = w.normalized();
  if (!(unit.z() > 0))
    Malformed(path, line, "light below the object's horizon (z = " + std::to_string(unit.z()) +
                              " <= 0; z points towards the camera): check the axis convention");
  return unit;
}

const char* DepthName(int depth) {
  switch (depth) {
    case CV_8U: return "8-bit";
    case CV_16U: return "16-bit";
    case CV_32F: return "32-bit float";
    default: return "unusual-depth";
  }
}

// Ground-truth normals: a real double H x W x 3 array whose vectors inside the
// object are unit length. Vectors that are not (DiLiGenT's zeros off the
// object, or a damaged file) become NaN so that no evaluation counts them.
// A MATLAB 5 (or 7.3) file's 128-byte header: text, then version 0x0100
// (0x0200 for 7.3) and the endian mark "IM"/"MI" at bytes 124..127; for
// level 5 the first data element's size must fit the file. Checked before
// matio sees the file: it would take anything else for a headerless level 4
// file and trust sizes from garbage (gigabytes for a 23-byte file).
std::string MatHeaderProblem(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::array<unsigned char, 136> head{};
  in.read(reinterpret_cast<char*>(head.data()), head.size());
  const std::streamsize got = in.gcount();
  if (got < 128) return "shorter than a MATLAB file's 128-byte header";
  const bool little = head[126] == 'I' && head[127] == 'M', big = head[126] == 'M' && head[127] == 'I';
  if (!little && !big) return "not a MATLAB 5 or 7.3 file (no endian mark in its header)";
  const unsigned version = little ? head[124] | head[125] << 8 : head[125] | head[124] << 8;
  if (version == 0x0200) return {};  // 7.3: an HDF5 file, read by matio's HDF5 support
  if (version != 0x0100) return "not a MATLAB 5 or 7.3 file (header version " + std::to_string(version) + ")";
  if (got < 136) return "no data after the header";
  const auto word = [&](int at) {
    return little ? std::uint32_t(head[at]) | std::uint32_t(head[at + 1]) << 8 | std::uint32_t(head[at + 2]) << 16 |
                        std::uint32_t(head[at + 3]) << 24
                  : std::uint32_t(head[at + 3]) | std::uint32_t(head[at + 2]) << 8 | std::uint32_t(head[at + 1]) << 16 |
                        std::uint32_t(head[at]) << 24;
  };
  std::error_code error;
  const std::uintmax_t size = fs::file_size(path, error);
  if (error) return "cannot tell its size (" + error.message() + ")";
  if (word(132) > size - 136) return "its first variable claims " + std::to_string(word(132)) + " bytes of a " +
                                     std::to_string(size) + "-byte file (truncated or damaged)";
  return {};
}

cv::Mat ReadNormalsMat(const fs::path& path, cv::Size size, const cv::Mat& object_mask) {
  if (const std::string problem = MatHeaderProblem(path); !problem.empty()) Malformed(path, 0, problem);
  mat_t* file = Mat_Open(path.c_str(), MAT_ACC_RDONLY);
  if (!file) Malformed(path, 0, "cannot open as a MATLAB file");
  matvar_t* variable = Mat_VarReadInfo(file, "Normal_gt");
  if (!variable) {
    Mat_Close(file);
    Malformed(path, 0, "no variable Normal_gt (missing, or the file is truncated)");
  }
  const bool shape_ok = variable->rank == 3 && variable->dims[0] == static_cast<size_t>(size.height) &&
                        variable->dims[1] == static_cast<size_t>(size.width) && variable->dims[2] == 3 &&
                        variable->class_type == MAT_C_DOUBLE && !variable->isComplex;
  cv::Mat normals;
  if (shape_ok) {
    normals.create(size, CV_32FC3);
    const std::size_t h = size.height, w = size.width;
    // Read into NaNs: matio fills a truncated file's missing tail with whatever
    // the buffer held, and NaN is what the unit-length check below refuses.
    std::vector<double> values(h * w * 3, std::numeric_limits<double>::quiet_NaN());
    int start[3] = {0, 0, 0}, stride[3] = {1, 1, 1}, edge[3] = {size.height, size.width, 3};
    Mat_VarReadData(file, variable, values.data(), start, stride, edge);
    const double* data = values.data();
    for (std::size_t r = 0; r < h; ++r)
      for (std::size_t c = 0; c < w; ++c) {
        cv::Vec3f& n = normals.at<cv::Vec3f>(r, c);
        for (int k = 0; k < 3; ++k)  // MATLAB arrays are column-major
          n[k] = static_cast<float>(data[r + h * (c + w * k)]);
        if (!(std::abs(cv::norm(n) - 1.0) < 0.01)) n = cv::Vec3f::all(std::numeric_limits<float>::quiet_NaN());
      }
  }
  Mat_VarFree(variable);
  Mat_Close(file);
  if (!shape_ok)
    Malformed(path, 0, "Normal_gt must be a real double array of " + std::to_string(size.height) + " x " +
                           std::to_string(size.width) + " x 3 (the images' size)");
  // Half the object without unit normals is not ground truth but a damaged file.
  int inside = 0, unit = 0;
  for (int r = 0; r < size.height; ++r)
    for (int c = 0; c < size.width; ++c) {
      if (!object_mask.empty() && !object_mask.at<std::uint8_t>(r, c)) continue;
      ++inside;
      unit += std::isfinite(normals.at<cv::Vec3f>(r, c)[0]) ? 1 : 0;
    }
  if (unit == 0 || (!object_mask.empty() && unit < inside / 2))
    Malformed(path, 0, "Normal_gt has unit normals at " + std::to_string(unit) + " of " + std::to_string(inside) +
                           " object pixels: the file is damaged or not ground-truth normals");
  return normals;
}

void WriteNormalsMat(const fs::path& path, const cv::Mat& normals) {
  const std::size_t h = normals.rows, w = normals.cols;
  std::vector<double> data(h * w * 3);
  for (std::size_t r = 0; r < h; ++r)
    for (std::size_t c = 0; c < w; ++c)
      for (int k = 0; k < 3; ++k) {
        const float v = normals.at<cv::Vec3f>(r, c)[k];
        data[r + h * (c + w * k)] = std::isfinite(v) ? v : 0.0;  // DiLiGenT stores 0 off the object
      }
  mat_t* file = Mat_CreateVer(path.c_str(), nullptr, MAT_FT_MAT5);
  if (!file) throw std::runtime_error("cannot create " + path.string());
  size_t dims[3] = {h, w, 3};
  matvar_t* variable = Mat_VarCreate("Normal_gt", MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dims, data.data(), 0);
  const int status = Mat_VarWrite(file, variable, MAT_COMPRESSION_NONE);
  Mat_VarFree(variable);
  Mat_Close(file);
  if (status != 0) throw std::runtime_error("cannot write " + path.string());
}

}  // namespace

PhotometricStereoInput LoadDiligent(const std::string& directory) {
  const fs::path root(directory);
  PhotometricStereoInput input;
  input.source = directory;
  const fs::path names_file = root / "filenames.txt";
  const auto names = ReadLines(names_file);
  if (names.size() < 3) Malformed(names_file, 0, "fewer than 3 images; photometric stereo needs at least 3 lights");
  std::map<std::string, int> first_line;
  for (const auto& [number, name] : names) {
    const auto [it, fresh] = first_line.emplace(name, number);
    if (!fresh) Malformed(names_file, number, "'" + name + "' is listed twice (first on line " + std::to_string(it->second) + ")");
  }
  const fs::path directions_file = root / "light_directions.txt", intensities_file = root / "light_intensities.txt";
  const auto directions = ReadTriples(directions_file, names.size());
  const auto intensities = ReadTriples(intensities_file, names.size());
  // Decoding and converting are most of a load (96 PNGs for DiLiGenT): the
  // first image sizes the stack's slabs, then the frames are made on every
  // core and checked and kept in file order, so the fault reported is the
  // first the file order meets.
  std::vector<FolderFrame> frames(names.size());
  std::vector<std::exception_ptr> failures(frames.size());
  cv::Mat grey_slab, rgb_slab;
  if (const cv::Mat head = DecodeFolderImage(root / names[0].second, &frames[0].why); !head.empty()) {
    const int count = static_cast<int>(frames.size()), rows = head.rows;
    grey_slab = AllocateFrameSlab(count, head.size(), CV_32F);
    if (head.channels() == 3) rgb_slab = AllocateFrameSlab(count, head.size(), CV_32FC3);
    auto slice = [&](const cv::Mat& slab, std::size_t i) {
      return slab.empty() ? cv::Mat() : FrameOfSlab(slab, static_cast<int>(i), rows);
    };
    frames[0] = ConvertFolderFrame(head, intensities[0].second, nullptr, slice(grey_slab, 0), slice(rgb_slab, 0));
    failures = LoadOnEveryCore(frames.size(), [&](std::size_t i) {
      if (i > 0)  // the first is made
        frames[i] = ReadFolderFrame(root / names[i].second, intensities[i].second, frames[0], slice(grey_slab, i),
                                    slice(rgb_slab, i));
    });
  }
  const FolderFrame* first = nullptr;
  bool colour_seen = false;
  for (std::size_t i = 0; i < names.size(); ++i) {
    const fs::path file = root / names[i].second;
    // The error_code form: a name the system refuses (longer than a file
    // name may be, say) is the line's fault, not an escaped filesystem_error.
    std::error_code error;
    if (!fs::is_regular_file(file, error))
      Malformed(names_file, names[i].first,
                "'" + names[i].second + "' is not a file in " + root.string() + (error ? " (" + error.message() + ")" : ""));
    FolderFrame& frame = frames[i];
    if (failures[i]) std::rethrow_exception(failures[i]);
    if (!frame.why.empty()) Malformed(file, 0, "cannot read as an image (" + frame.why + ")");
    if (!first) {
      first = &frame;
    } else if (frame.size != first->size || frame.depth != first->depth || frame.channels != first->channels) {
      // Mixed bit depths solve with "success" at several times the error: the
      // 8-bit images are 257 times too dark for their light.
      Malformed(file, 0, std::to_string(frame.size.width) + "x" + std::to_string(frame.size.height) + " " +
                             DepthName(frame.depth) + " with " + std::to_string(frame.channels) + " channel(s), but " +
                             names[0].second + " is " + std::to_string(first->size.width) + "x" +
                             std::to_string(first->size.height) + " " + DepthName(first->depth) + " with " +
                             std::to_string(first->channels) +
                             ": every image of a stack must share size, bit depth and channels (re-export it)");
    }
    const auto& [intensity_line, rgb] = intensities[i];
    for (int c = 0; c < 3; ++c)
      if (!(rgb[c] >= kMinLightIntensity && rgb[c] <= kMaxLightIntensity))
        Malformed(intensities_file, intensity_line, "intensities must lie in [1e-6, 1e6] (relative units, of order 1)");
    input.stack.images.push_back(FrameOfSlab(grey_slab, static_cast<int>(i), frame.size.height));
    input.stack.light_directions.push_back(LightDirection(directions_file, directions[i].first, directions[i].second));
    input.stack.light_scales.push_back((rgb[0] + rgb[1] + rgb[2]) / 3.0);
    colour_seen = colour_seen || frame.channels_differ;
    if (frame.channels == 3) {
      // Colour kept as well: each channel's albedo is fitted under that
      // channel's intensity once the normals are solved on the grey stack.
      if (!input.color) {
        input.color.emplace();
        input.color->provenance.mosaic = "RGB";
        input.color->provenance.demosaic = "none";
        input.color->provenance.color_space = "camera-rgb";
        input.color->provenance.light_colors = intensities_file.string() + " per channel";
      }
      input.color->images.push_back(FrameOfSlab(rgb_slab, static_cast<int>(i), frame.size.height));
      input.color->light_directions.push_back(input.stack.light_directions.back());
      input.color->light_scales.emplace_back(rgb[0], rgb[1], rgb[2]);  // light_intensities.txt: R G B
    }
  }
  if (!colour_seen) input.color.reset();
  // Channels are rescaled, so there is no common full-scale code to detect.
  input.saturation_level = std::numeric_limits<double>::infinity();
  const fs::path mask_file = root / "mask.png";
  std::error_code error;
  if (fs::exists(mask_file, error)) {
    cv::Mat mask = ReadFolderImage(mask_file);
    if (mask.size() != first->size)
      Malformed(mask_file, 0, std::to_string(mask.cols) + "x" + std::to_string(mask.rows) + ", but the images are " +
                                  std::to_string(first->size.width) + "x" + std::to_string(first->size.height));
    if (mask.channels() > 1) cv::extractChannel(mask, mask, 0);
    if (mask.depth() != CV_8U) mask.convertTo(mask, CV_8U, 1.0 / 257.0);
    input.object_mask = mask > 0;
    if (cv::countNonZero(input.object_mask) == 0)
      Malformed(mask_file, 0, "the mask is empty (no nonzero pixel): nothing to solve; fix or remove mask.png");
    input.mask_source = mask_file.string();
  }
  if (fs::exists(root / "Normal_gt.mat", error))
    input.truth_normals = ReadNormalsMat(root / "Normal_gt.mat", first->size, input.object_mask);
  return input;
}

void ExportDiligent(const std::string& run_directory, const std::string& output_directory) {
  const PhotometricStereoInput input = LoadRunStack(run_directory);
  const fs::path out(output_directory);
  fs::create_directories(out);
  std::string filenames, directions, intensities;
  char line[160];
  for (int k = 0; k < input.stack.light_count(); ++k) {
    cv::Mat signal = input.stack.images[k].clone();
    if (!input.stack.dark.empty()) signal -= input.stack.dark;
    cv::Mat grey16, rgb;
    signal.convertTo(grey16, CV_16U);  // saturates negatives at 0
    cv::merge(std::vector<cv::Mat>{grey16, grey16, grey16}, rgb);
    std::snprintf(line, sizeof(line), "%03d.png", k + 1);
    WriteImage((out / line).string(), rgb);
    filenames += std::string(line) + "\n";
    const Eigen::Vector3d& d = input.stack.light_directions[k];
    std::snprintf(line, sizeof(line), "%.9f %.9f %.9f\n", d.x(), d.y(), d.z());
    directions += line;
    const double s = input.stack.light_scales[k];
    std::snprintf(line, sizeof(line), "%.9g %.9g %.9g\n", s, s, s);
    intensities += line;
  }
  WriteFileDurably((out / "filenames.txt").string(), filenames);
  WriteFileDurably((out / "light_directions.txt").string(), directions);
  WriteFileDurably((out / "light_intensities.txt").string(), intensities);
  if (!input.truth_normals.empty()) {
    cv::Mat mask(input.truth_normals.size(), CV_8U);
    for (int r = 0; r < mask.rows; ++r)
      for (int c = 0; c < mask.cols; ++c) mask.at<std::uint8_t>(r, c) = std::isfinite(input.truth_normals.at<cv::Vec3f>(r, c)[0]) ? 255 : 0;
    WriteImage((out / "mask.png").string(), mask);
    WriteNormalsMat(out / "Normal_gt.mat", input.truth_normals);
  }
}

}  // namespace photorig::daemon
