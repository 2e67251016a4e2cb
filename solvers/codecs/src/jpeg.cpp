// JPEG on libjpeg (libjpeg-turbo), read from memory with OpenCV's settings
// (default IDCT and upsampling), so the pixels equal cv::imdecode's. libjpeg
// reports errors through error_exit, which longjmps back here: every call
// into libjpeg runs inside a function whose own state is plain data (a jump
// past a C++ object's destructor is undefined); the objects live in the
// caller.

#include "formats.h"

#include <algorithm>
#include <csetjmp>
#include <cstdio>  // jpeglib.h needs FILE and size_t declared first
#include <exception>

#include <jerror.h>
#include <jpeglib.h>

namespace photorig::solvers::codecs::internal {
namespace {

// The image and libjpeg's buffers together stay within 1.5 times the pixel
// limit (1.5 GiB at most). A progressive or multi-scan file keeps every
// coefficient while it is read (3 bytes a pixel at 4:2:0, 6 at 4:4:4), so
// the image alone would not bound a decode.
// Never below the pixel limit, so the buffers' share below is never negative.
std::uint64_t MemoryLimit(std::uint64_t max_pixel_bytes) { return max_pixel_bytes + max_pixel_bytes / 2; }
// A progressive file has about ten scans; each scan walks the whole image,
// so a few bytes of repeated scans would otherwise buy minutes of decoding.
constexpr int kMaxScans = 500;

struct Decoder {
  jpeg_decompress_struct info{};
  jpeg_error_mgr errors{};
  jpeg_source_mgr source{};
  jpeg_progress_mgr progress{};
  std::jmp_buf jump{};
  char message[JMSG_LENGTH_MAX] = "";
  // The limits (DecodeOptions), and as the reasons name them: formatted
  // before decoding, as the functions that jump back keep no std::string.
  std::uint64_t max_pixel_bytes = 0;
  char pixel_limit[32] = "", memory_limit[32] = "";
  ~Decoder() { jpeg_destroy_decompress(&info); }  // safe before jpeg_create_decompress too: info.mem is null
};

constexpr char kTruncated[] = "the file ends early (truncated)";

Decoder& DecoderOf(j_common_ptr info) { return *static_cast<Decoder*>(info->client_data); }

[[noreturn]] void Fail(j_common_ptr info) {
  Decoder& decoder = DecoderOf(info);
  if (info->err->msg_code == JERR_CANT_SUSPEND)  // the arithmetic decoder, out of input
    std::snprintf(decoder.message, sizeof decoder.message, "%s", kTruncated);
  else if (info->err->msg_code == JERR_NO_BACKING_STORE)  // libjpeg's way of saying max_memory_to_use is exceeded
    std::snprintf(decoder.message, sizeof decoder.message, "decoding it takes more than %s of memory",
                  decoder.memory_limit);
  else
    (*info->err->format_message)(info, decoder.message);
  std::longjmp(decoder.jump, 1);
}

// A warning (level -1) means libjpeg patched over damaged data (a bad Huffman
// code, a missing restart marker, a scan out of order): the pixels would not
// be the file's, so it fails the decode. Two warnings are only about header
// fields libjpeg does not know, and trace messages (level >= 0) are notes.
void OnMessage(j_common_ptr info, int level) {
  const int code = info->err->msg_code;
  if (level < 0 && code != JWRN_JFIF_MAJOR && code != JWRN_ADOBE_XFORM) Fail(info);
}

void LimitScans(j_common_ptr info) {
  Decoder& decoder = DecoderOf(info);
  if (decoder.info.input_scan_number <= kMaxScans) return;
  std::snprintf(decoder.message, sizeof decoder.message, "more than %d scans", kMaxScans);
  std::longjmp(decoder.jump, 1);
}

void NoSourceAction(j_decompress_ptr) {}

// The whole file is in the buffer from the start, so a request for more
// means it ends early. FALSE suspends the decoder (OpenCV's memory source
// does the same); Start and ReadRows report a suspension as a truncated file.
boolean NoMoreInput(j_decompress_ptr) { return FALSE; }

// A skip past the end empties the buffer; the next read then suspends.
void SkipInput(j_decompress_ptr info, long count) {
  jpeg_source_mgr* source = info->src;
  const std::size_t skip = count <= 0 ? 0 : std::min(static_cast<std::size_t>(count), source->bytes_in_buffer);
  source->next_input_byte += skip;
  source->bytes_in_buffer -= skip;
}

bool Truncated(Decoder* decoder) {
  std::snprintf(decoder->message, sizeof decoder->message, "%s", kTruncated);
  return false;
}

// Reads the header and starts decompressing to grey, B, G, R, or C, M, Y, K
// for a four-component file (converted row by row below). False with
// `message` set on an error, a truncated header or an image past the limit.
bool Start(Decoder* decoder, const std::uint8_t* bytes, std::size_t size) {
  jpeg_decompress_struct* info = &decoder->info;
  if (setjmp(decoder->jump)) return false;
  info->err = jpeg_std_error(&decoder->errors);
  decoder->errors.error_exit = Fail;
  decoder->errors.emit_message = OnMessage;
  info->client_data = decoder;  // jpeg_create_decompress keeps err and client_data
  jpeg_create_decompress(info);
  decoder->progress.progress_monitor = LimitScans;
  info->progress = &decoder->progress;
  decoder->source.next_input_byte = bytes;
  decoder->source.bytes_in_buffer = size;
  decoder->source.init_source = NoSourceAction;
  decoder->source.fill_input_buffer = NoMoreInput;
  decoder->source.skip_input_data = SkipInput;
  decoder->source.resync_to_restart = jpeg_resync_to_restart;
  decoder->source.term_source = NoSourceAction;
  info->src = &decoder->source;
  if (jpeg_read_header(info, TRUE) != JPEG_HEADER_OK) return Truncated(decoder);
  // OpenCV's layout: one component is grey, any other count colour; libjpeg
  // refuses the conversion for two components or more than four.
  const int channels = info->num_components == 1 ? 1 : 3;
  const std::uint64_t image_bytes = std::uint64_t{info->image_width} * info->image_height * channels;
  if (image_bytes > decoder->max_pixel_bytes) {
    std::snprintf(decoder->message, sizeof decoder->message, "%u x %u pixels, past the %s limit",
                  info->image_width, info->image_height, decoder->pixel_limit);
    return false;
  }
  info->mem->max_memory_to_use = static_cast<long>(MemoryLimit(decoder->max_pixel_bytes) - image_bytes);
  info->out_color_space = channels == 1 ? JCS_GRAYSCALE : info->num_components == 4 ? JCS_CMYK : JCS_EXT_BGR;
  if (!jpeg_start_decompress(info)) return Truncated(decoder);  // a multi-scan file is read whole here
  return true;
}

// OpenCV's conversion (imgcodecs' icvCvt_CMYK2BGR_8u_C4C3R), for equal pixels.
void CmykToBgr(const JSAMPLE* cmyk, std::uint8_t* bgr, JDIMENSION width) {
  for (JDIMENSION x = 0; x < width; ++x, cmyk += 4, bgr += 3) {
    const int k = cmyk[3];
    bgr[0] = static_cast<std::uint8_t>(k - (((255 - cmyk[2]) * k) >> 8));
    bgr[1] = static_cast<std::uint8_t>(k - (((255 - cmyk[1]) * k) >> 8));
    bgr[2] = static_cast<std::uint8_t>(k - (((255 - cmyk[0]) * k) >> 8));
  }
}

// Decodes every row into `pixels`. What follows the last row (the end
// marker, trailing bytes) is not read: the image is whole, and OpenCV
// ignores it as well.
bool ReadRows(Decoder* decoder, std::uint8_t* pixels, std::size_t step) {
  jpeg_decompress_struct* info = &decoder->info;
  if (setjmp(decoder->jump)) return false;
  if (info->out_color_space != JCS_CMYK) {
    for (JDIMENSION y = 0; y < info->output_height; ++y) {
      JSAMPROW row = pixels + y * step;
      if (jpeg_read_scanlines(info, &row, 1) != 1) return Truncated(decoder);
    }
    return true;
  }
  JSAMPARRAY cmyk =
      (*info->mem->alloc_sarray)(reinterpret_cast<j_common_ptr>(info), JPOOL_IMAGE, info->output_width * 4, 1);
  for (JDIMENSION y = 0; y < info->output_height; ++y) {
    if (jpeg_read_scanlines(info, cmyk, 1) != 1) return Truncated(decoder);
    CmykToBgr(cmyk[0], pixels + y * step, info->output_width);
  }
  return true;
}

}  // namespace

cv::Mat DecodeJpeg(std::span<const std::uint8_t> bytes, std::string* why, std::uint64_t max_pixel_bytes) {
  Decoder decoder;
  decoder.max_pixel_bytes = max_pixel_bytes;
  std::snprintf(decoder.pixel_limit, sizeof decoder.pixel_limit, "%s", LimitText(max_pixel_bytes).c_str());
  std::snprintf(decoder.memory_limit, sizeof decoder.memory_limit, "%s",
                LimitText(MemoryLimit(max_pixel_bytes)).c_str());
  if (!Start(&decoder, bytes.data(), bytes.size())) {
    *why = std::string("JPEG: ") + decoder.message;
    return {};
  }
  const jpeg_decompress_struct& info = decoder.info;
  cv::Mat image;
  try {
    image.create(static_cast<int>(info.output_height), static_cast<int>(info.output_width),
                 info.out_color_space == JCS_GRAYSCALE ? CV_8UC1 : CV_8UC3);
  } catch (const std::exception&) {
    *why = "JPEG: out of memory for " + std::to_string(info.output_width) + " x " +
           std::to_string(info.output_height) + " pixels";
    return {};
  }
  if (!ReadRows(&decoder, image.data, image.step[0])) {
    *why = std::string("JPEG: ") + decoder.message;
    return {};
  }
  return image;
}

}  // namespace photorig::solvers::codecs::internal
