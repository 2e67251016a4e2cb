// PNG on libpng. libpng reports errors by longjmp, so every call that can
// fail runs inside a function whose locals are plain data (a jump past a C++
// object's destructor is undefined); the objects live in the callers.

#include "formats.h"

#include <png.h>

#include <cstdio>
#include <cstring>

namespace photorig::solvers::codecs::internal {
namespace {

struct ErrorState {
  char message[200] = "";
};

void OnError(png_structp png, png_const_charp message) {
  auto* state = static_cast<ErrorState*>(png_get_error_ptr(png));
  std::snprintf(state->message, sizeof state->message, "%s", message);
  png_longjmp(png, 1);
}

void OnWarning(png_structp, png_const_charp) {}  // an ancillary chunk's fault; the pixels stand

struct MemoryReader {
  const std::uint8_t* data;
  std::size_t size;
  std::size_t offset;
};

void ReadFromMemory(png_structp png, png_bytep out, png_size_t length) {
  auto* reader = static_cast<MemoryReader*>(png_get_io_ptr(png));
  if (length > reader->size - reader->offset) png_error(png, "the file ends early (truncated)");
  std::memcpy(out, reader->data + reader->offset, length);
  reader->offset += length;
}

struct Header {
  png_uint_32 width, height;
  int bit_depth, color_type;
  bool has_transparency;
};

bool ReadHeader(png_structp png, png_infop info, Header* header) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_info(png, info);
  png_get_IHDR(png, info, &header->width, &header->height, &header->bit_depth, &header->color_type, nullptr, nullptr,
               nullptr);
  header->has_transparency = png_get_valid(png, info, PNG_INFO_tRNS) != 0;
  return true;
}

// Transforms to OpenCV's layout: grey or B, G, R(, A); 16-bit words native;
// palettes and grey below 8 bits expanded. `channels` is the layout's count.
bool ReadPixels(png_structp png, png_infop info, const Header& header, int channels, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  if (header.bit_depth == 16) png_set_swap(png);
  if (channels == 4) png_set_tRNS_to_alpha(png); else png_set_strip_alpha(png);
  if (header.color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (!(header.color_type & PNG_COLOR_MASK_COLOR) && header.bit_depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if (header.color_type & PNG_COLOR_MASK_COLOR) png_set_bgr(png);
  else if (channels > 1) png_set_gray_to_rgb(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  png_read_image(png, rows);
  png_read_end(png, nullptr);
  return true;
}

struct ReadStructs {
  png_structp png = nullptr;
  png_infop info = nullptr;
  ~ReadStructs() { png_destroy_read_struct(&png, &info, nullptr); }
};

struct MemoryWriter {
  std::vector<std::uint8_t>* out;
};

void WriteToMemory(png_structp png, png_bytep data, png_size_t length) {
  auto* writer = static_cast<MemoryWriter*>(png_get_io_ptr(png));
  writer->out->insert(writer->out->end(), data, data + length);
}

void FlushMemory(png_structp) {}

bool WritePixels(png_structp png, png_infop info, const cv::Mat& image, int compression_level, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  const int channels = image.channels();
  const int color_type = channels == 1   ? PNG_COLOR_TYPE_GRAY
                         : channels == 3 ? PNG_COLOR_TYPE_RGB
                                         : PNG_COLOR_TYPE_RGB_ALPHA;
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.cols), static_cast<png_uint_32>(image.rows),
               image.depth() == CV_16U ? 16 : 8, color_type, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, compression_level);
  // At the fast levels previews and masks are written at, one fixed filter
  // and run-length matching spare libpng trying every filter on every row.
  if (compression_level <= 3) {
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
    png_set_compression_strategy(png, 3 /* Z_RLE */);
  }
  png_write_info(png, info);
  if (image.depth() == CV_16U) png_set_swap(png);
  if (channels > 1) png_set_bgr(png);
  png_write_image(png, rows);
  png_write_end(png, info);
  return true;
}

struct WriteStructs {
  png_structp png = nullptr;
  png_infop info = nullptr;
  ~WriteStructs() { png_destroy_write_struct(&png, &info); }
};

}  // namespace

cv::Mat DecodePng(std::span<const std::uint8_t> bytes, std::string* why, std::uint64_t max_pixel_bytes) {
  ErrorState error;
  ReadStructs structs;
  structs.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &error, OnError, OnWarning);
  if (structs.png) structs.info = png_create_info_struct(structs.png);
  if (!structs.info) {
    *why = "PNG: out of memory";
    return {};
  }
  MemoryReader reader{bytes.data(), bytes.size(), 0};
  png_set_read_fn(structs.png, &reader, ReadFromMemory);
  Header header{};
  if (!ReadHeader(structs.png, structs.info, &header)) {
    *why = std::string("PNG: ") + error.message;
    return {};
  }
  // OpenCV's layout: alpha (or a transparent colour) makes four channels,
  // colour three, grey one; a transparent grey stays grey.
  const bool colour = header.color_type & PNG_COLOR_MASK_COLOR;
  const bool alpha = (header.color_type & PNG_COLOR_MASK_ALPHA) || (colour && header.has_transparency);
  const int channels = alpha ? 4 : colour ? 3 : 1;
  const int depth = header.bit_depth == 16 ? CV_16U : CV_8U;
  const std::uint64_t pixel_bytes = std::uint64_t{header.width} * header.height * channels * (depth == CV_16U ? 2 : 1);
  if (header.width > static_cast<png_uint_32>(INT32_MAX) || header.height > static_cast<png_uint_32>(INT32_MAX) ||
      pixel_bytes > max_pixel_bytes) {
    *why = "PNG: " + std::to_string(header.width) + " x " + std::to_string(header.height) +
           " pixels, past the " + LimitText(max_pixel_bytes) + " limit";
    return {};
  }
  cv::Mat image(static_cast<int>(header.height), static_cast<int>(header.width), CV_MAKETYPE(depth, channels));
  std::vector<png_bytep> rows(header.height);
  for (int r = 0; r < image.rows; ++r) rows[r] = image.ptr(r);
  if (!ReadPixels(structs.png, structs.info, header, channels, rows.data())) {
    *why = std::string("PNG: ") + error.message;
    return {};
  }
  return image;
}

bool EncodePng(const cv::Mat& image, int compression_level, std::vector<std::uint8_t>* out, std::string* why) {
  const int channels = image.channels();
  if ((image.depth() != CV_8U && image.depth() != CV_16U) || (channels != 1 && channels != 3 && channels != 4) ||
      image.empty()) {
    *why = "PNG holds 8- or 16-bit images of 1, 3 or 4 channels";
    return false;
  }
  ErrorState error;
  WriteStructs structs;
  structs.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, OnError, OnWarning);
  if (structs.png) structs.info = png_create_info_struct(structs.png);
  if (!structs.info) {
    *why = "PNG: out of memory";
    return false;
  }
  MemoryWriter writer{out};
  png_set_write_fn(structs.png, &writer, WriteToMemory, FlushMemory);
  std::vector<png_bytep> rows(image.rows);
  for (int r = 0; r < image.rows; ++r) rows[r] = const_cast<png_bytep>(image.ptr(r));
  if (!WritePixels(structs.png, structs.info, image, compression_level, rows.data())) {
    *why = std::string("PNG: ") + error.message;
    return false;
  }
  return true;
}

}  // namespace photorig::solvers::codecs::internal
