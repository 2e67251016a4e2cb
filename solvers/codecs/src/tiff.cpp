// TIFF on libtiff, read from and written to memory. Errors and warnings go
// to handlers of the one handle (libtiff's global handlers print to stderr
// and are shared between threads decoding a stack).

#include "formats.h"
#include "photorig/solvers/codecs/image_codecs.h"

#include <opencv2/core.hpp>
#include <tiffio.h>

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <memory>

namespace photorig::solvers::codecs::internal {
namespace {

struct Stream {
  std::vector<std::uint8_t> written;        // for writing
  std::span<const std::uint8_t> readable;  // for reading
  std::uint64_t position = 0;
  char message[200] = "";
  std::uint64_t Size() const { return readable.empty() ? written.size() : readable.size(); }
};

Stream& StreamOf(thandle_t handle) { return *static_cast<Stream*>(handle); }

tmsize_t Read(thandle_t handle, void* out, tmsize_t size) {
  Stream& s = StreamOf(handle);
  if (size < 0 || s.position >= s.readable.size()) return 0;
  const std::uint64_t n = std::min<std::uint64_t>(static_cast<std::uint64_t>(size), s.readable.size() - s.position);
  std::memcpy(out, s.readable.data() + s.position, n);
  s.position += n;
  return static_cast<tmsize_t>(n);
}

tmsize_t Write(thandle_t handle, void* data, tmsize_t size) {
  Stream& s = StreamOf(handle);
  if (size < 0) return -1;
  const std::uint64_t end = s.position + static_cast<std::uint64_t>(size);
  if (end > s.written.size()) s.written.resize(end);
  std::memcpy(s.written.data() + s.position, data, static_cast<std::size_t>(size));
  s.position = end;
  return size;
}

tmsize_t NoWrite(thandle_t, void*, tmsize_t) { return -1; }

toff_t Seek(thandle_t handle, toff_t offset, int whence) {
  Stream& s = StreamOf(handle);
  const std::uint64_t base = whence == SEEK_CUR ? s.position : whence == SEEK_END ? s.Size() : 0;
  s.position = base + offset;
  return s.position;
}

int Close(thandle_t) { return 0; }
toff_t SizeOf(thandle_t handle) { return StreamOf(handle).Size(); }
int NoMap(thandle_t, void**, toff_t*) { return 0; }
void NoUnmap(thandle_t, void*, toff_t) {}

int KeepError(TIFF*, void* user_data, const char* module, const char* format, va_list args) {
  Stream& s = *static_cast<Stream*>(user_data);
  if (s.message[0] != '\0') return 1;  // the first error is the cause; later ones follow from it
  const int used = std::snprintf(s.message, sizeof s.message, "%s: ", module ? module : "TIFF");
  if (used >= 0 && static_cast<std::size_t>(used) < sizeof s.message)
    std::vsnprintf(s.message + used, sizeof s.message - used, format, args);
  return 1;
}

int IgnoreWarning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

struct TiffCloser {
  void operator()(TIFF* tif) const { TIFFClose(tif); }
};
using TiffHandle = std::unique_ptr<TIFF, TiffCloser>;

TiffHandle Open(Stream* stream, const char* mode) {
  TIFFOpenOptions* options = TIFFOpenOptionsAlloc();
  // libtiff's own buffers (a codec's tables, a strip) are held to the most
  // any image may take; the image itself is checked against the caller's
  // limit from the header (DecodeTiff).
  TIFFOpenOptionsSetMaxSingleMemAlloc(options, static_cast<tmsize_t>(kMaxDecodedBytes));
  TIFFOpenOptionsSetErrorHandlerExtR(options, KeepError, stream);
  TIFFOpenOptionsSetWarningHandlerExtR(options, IgnoreWarning, nullptr);
  TIFF* tif = TIFFClientOpenExt("memory", mode, stream, Read, mode[0] == 'w' ? Write : NoWrite, Seek, Close, SizeOf,
                                NoMap, NoUnmap, options);
  TIFFOpenOptionsFree(options);
  return TiffHandle(tif);
}

std::string Reason(const Stream& stream, const char* fallback) {
  return std::string("TIFF: ") + (stream.message[0] != '\0' ? stream.message : fallback);
}

struct Layout {
  std::uint32_t width = 0, height = 0;
  std::uint16_t samples = 1, bits = 1, format = SAMPLEFORMAT_UINT, photometric = PHOTOMETRIC_MINISBLACK,
                planar = PLANARCONFIG_CONTIG;
  int Depth() const {
    if (format == SAMPLEFORMAT_UINT && bits == 8) return CV_8U;
    if (format == SAMPLEFORMAT_UINT && bits == 16) return CV_16U;
    if (format == SAMPLEFORMAT_IEEEFP && bits == 32) return CV_32F;
    return -1;
  }
  // Samples libtiff hands over as stored: grey or RGB with at most one extra
  // sample, 8- or 16-bit unsigned or 32-bit float.
  bool Direct() const {
    const bool grey = photometric == PHOTOMETRIC_MINISBLACK && samples == 1;
    const bool rgb = photometric == PHOTOMETRIC_RGB && (samples == 3 || samples == 4);
    return Depth() >= 0 && (grey || rgb);
  }
};

// The file's channel order (R, G, B(, A)) and OpenCV's (B, G, R(, A)) differ
// by a swap that is its own inverse.
cv::Mat SwapRedAndBlue(const cv::Mat& in, int out_channels) {
  cv::Mat out(in.size(), CV_MAKETYPE(in.depth(), out_channels));
  cv::mixChannels(in, out, out_channels == 3 ? std::vector<int>{0, 2, 1, 1, 2, 0} : std::vector<int>{0, 2, 1, 1, 2, 0, 3, 3});
  return out;
}

// Copies `rows` x `cols` samples of `channels` from a strip or tile laid out
// with `in_row_bytes` into `out` at (row, col).
void CopyBlock(const std::uint8_t* in, std::size_t in_row_bytes, int rows, int cols, cv::Mat* out, int row, int col) {
  const std::size_t bytes = static_cast<std::size_t>(cols) * out->elemSize();
  for (int r = 0; r < rows; ++r) std::memcpy(out->ptr(row + r) + col * out->elemSize(), in + r * in_row_bytes, bytes);
}

// One plane (all samples when contiguous, one when planes are separate), read
// strip by strip or tile by tile.
bool ReadPlane(TIFF* tif, const Layout& layout, std::uint16_t plane, cv::Mat* out, std::vector<std::uint8_t>* buffer) {
  const std::size_t pixel_bytes = out->elemSize();
  if (TIFFIsTiled(tif)) {
    std::uint32_t tile_width = 0, tile_length = 0;
    TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tile_width);
    TIFFGetField(tif, TIFFTAG_TILELENGTH, &tile_length);
    const tmsize_t tile_bytes = TIFFTileSize(tif);
    if (tile_width == 0 || tile_length == 0 || tile_bytes <= 0 ||
        static_cast<std::uint64_t>(tile_bytes) < std::uint64_t{tile_width} * tile_length * pixel_bytes)
      return false;
    buffer->resize(static_cast<std::size_t>(tile_bytes));
    for (std::uint32_t y = 0; y < layout.height; y += tile_length)
      for (std::uint32_t x = 0; x < layout.width; x += tile_width) {
        if (TIFFReadEncodedTile(tif, TIFFComputeTile(tif, x, y, 0, plane), buffer->data(), tile_bytes) < 0)
          return false;
        CopyBlock(buffer->data(), tile_width * pixel_bytes, static_cast<int>(std::min(tile_length, layout.height - y)),
                  static_cast<int>(std::min(tile_width, layout.width - x)), out, static_cast<int>(y),
                  static_cast<int>(x));
      }
    return true;
  }
  std::uint32_t rows_per_strip = layout.height;
  TIFFGetFieldDefaulted(tif, TIFFTAG_ROWSPERSTRIP, &rows_per_strip);
  rows_per_strip = std::clamp<std::uint32_t>(rows_per_strip, 1, layout.height);
  const std::size_t row_bytes = layout.width * pixel_bytes;
  buffer->resize(row_bytes * rows_per_strip);
  for (std::uint32_t y = 0; y < layout.height; y += rows_per_strip) {
    const std::uint32_t rows = std::min(rows_per_strip, layout.height - y);
    const tmsize_t wanted = static_cast<tmsize_t>(row_bytes * rows);
    const tmsize_t got = TIFFReadEncodedStrip(tif, TIFFComputeStrip(tif, y, plane), buffer->data(), wanted);
    if (got < wanted) return false;
    CopyBlock(buffer->data(), row_bytes, static_cast<int>(rows), static_cast<int>(layout.width), out,
              static_cast<int>(y), 0);
  }
  return true;
}

cv::Mat ReadDirect(TIFF* tif, const Layout& layout, Stream* stream, std::string* why) {
  const int rows = static_cast<int>(layout.height), cols = static_cast<int>(layout.width);
  std::vector<std::uint8_t> buffer;
  cv::Mat stored;  // channels in the file's order (R, G, B, A)
  if (layout.planar == PLANARCONFIG_CONTIG || layout.samples == 1) {
    stored.create(rows, cols, CV_MAKETYPE(layout.Depth(), layout.samples));
    if (!ReadPlane(tif, layout, 0, &stored, &buffer)) {
      *why = Reason(*stream, "a strip or tile is missing or corrupt");
      return {};
    }
  } else {
    std::vector<cv::Mat> planes(layout.samples);
    for (std::uint16_t s = 0; s < layout.samples; ++s) {
      planes[s].create(rows, cols, layout.Depth());
      if (!ReadPlane(tif, layout, s, &planes[s], &buffer)) {
        *why = Reason(*stream, "a strip or tile is missing or corrupt");
        return {};
      }
    }
    cv::merge(planes, stored);
  }
  return layout.samples == 1 ? stored : SwapRedAndBlue(stored, layout.samples);
}

// Palettes, bilevel, YCbCr, CMYK and the like through libtiff's RGBA
// reader: 8-bit B, G, R, with alpha where the file has an extra sample.
cv::Mat ReadAsRgba(TIFF* tif, const Layout& layout, Stream* stream, std::string* why) {
  char reason[1024] = "";
  if (!TIFFRGBAImageOK(tif, reason)) {
    *why = std::string("TIFF: ") + reason;
    return {};
  }
  cv::Mat rgba(static_cast<int>(layout.height), static_cast<int>(layout.width), CV_8UC4);
  if (!TIFFReadRGBAImageOriented(tif, layout.width, layout.height, rgba.ptr<std::uint32_t>(), ORIENTATION_TOPLEFT, 0)) {
    *why = Reason(*stream, "cannot decode its pixels");
    return {};
  }
  // Each pixel is a word A << 24 | B << 16 | G << 8 | R: bytes R, G, B, A.
  return SwapRedAndBlue(rgba, layout.samples == 2 || layout.samples == 4 ? 4 : 3);
}

}  // namespace

cv::Mat DecodeTiff(std::span<const std::uint8_t> bytes, std::string* why, std::uint64_t max_pixel_bytes) {
  Stream stream;
  stream.readable = bytes;
  TiffHandle tif = Open(&stream, "r");
  if (!tif) {
    *why = Reason(stream, "not a readable TIFF");
    return {};
  }
  Layout layout;
  TIFFGetField(tif.get(), TIFFTAG_IMAGEWIDTH, &layout.width);
  TIFFGetField(tif.get(), TIFFTAG_IMAGELENGTH, &layout.height);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLESPERPIXEL, &layout.samples);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_BITSPERSAMPLE, &layout.bits);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLEFORMAT, &layout.format);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_PLANARCONFIG, &layout.planar);
  if (!TIFFGetField(tif.get(), TIFFTAG_PHOTOMETRIC, &layout.photometric))
    layout.photometric = layout.samples >= 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK;
  // What the reader allocates: the samples as stored, or libtiff's RGBA words.
  const std::uint64_t pixel_bytes = std::uint64_t{layout.width} * layout.height *
                                    (layout.Direct() ? layout.samples * (layout.bits / 8) : 4);
  if (layout.width == 0 || layout.height == 0 || layout.width > INT32_MAX || layout.height > INT32_MAX ||
      pixel_bytes > max_pixel_bytes) {
    *why = "TIFF: " + std::to_string(layout.width) + " x " + std::to_string(layout.height) +
           " pixels, empty or past the " + LimitText(max_pixel_bytes) + " limit";
    return {};
  }
  if (layout.Direct()) return ReadDirect(tif.get(), layout, &stream, why);
  // libtiff's RGBA reader would turn these into 8-bit colour, losing what a
  // float file is for.
  if (layout.photometric == PHOTOMETRIC_LOGLUV || layout.photometric == PHOTOMETRIC_LOGL) {
    *why = "TIFF: LogLuv-encoded pixels are not read (write float maps uncompressed or with LZW)";
    return {};
  }
  if (layout.bits > 8 && layout.bits != 16) {
    *why = "TIFF: " + std::to_string(layout.bits) + "-bit samples of format " + std::to_string(layout.format) +
           " are not read (8- or 16-bit unsigned, 32-bit float)";
    return {};
  }
  return ReadAsRgba(tif.get(), layout, &stream, why);
}

bool EncodeTiff(const cv::Mat& image, std::vector<std::uint8_t>* out, std::string* why) {
  const int channels = image.channels(), depth = image.depth();
  if ((depth != CV_8U && depth != CV_16U && depth != CV_32F) || (channels != 1 && channels != 3 && channels != 4) ||
      image.empty()) {
    *why = "TIFF holds 8- or 16-bit or float images of 1, 3 or 4 channels";
    return false;
  }
  Stream stream;
  {
    TiffHandle tif = Open(&stream, "w");
    if (!tif) {
      *why = Reason(stream, "cannot start a file");
      return false;
    }
    TIFF* t = tif.get();
    const std::uint16_t extra = EXTRASAMPLE_UNASSALPHA;
    bool ok = TIFFSetField(t, TIFFTAG_IMAGEWIDTH, static_cast<std::uint32_t>(image.cols)) &&
              TIFFSetField(t, TIFFTAG_IMAGELENGTH, static_cast<std::uint32_t>(image.rows)) &&
              TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, static_cast<std::uint16_t>(channels)) &&
              TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, static_cast<std::uint16_t>(image.elemSize1() * 8)) &&
              TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, depth == CV_32F ? SAMPLEFORMAT_IEEEFP : SAMPLEFORMAT_UINT) &&
              TIFFSetField(t, TIFFTAG_PHOTOMETRIC, channels == 1 ? PHOTOMETRIC_MINISBLACK : PHOTOMETRIC_RGB) &&
              TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG) &&
              TIFFSetField(t, TIFFTAG_COMPRESSION, COMPRESSION_LZW) &&
              // Differences of neighbouring integer samples compress; a float's
              // bytes differenced that way do not, and readers differ in
              // support for the floating-point predictor.
              TIFFSetField(t, TIFFTAG_PREDICTOR, depth == CV_32F ? PREDICTOR_NONE : PREDICTOR_HORIZONTAL) &&
              TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, TIFFDefaultStripSize(t, 0));
    if (ok && channels == 4) ok = TIFFSetField(t, TIFFTAG_EXTRASAMPLES, 1, &extra);
    // A copy of each row: the predictor differences the row it is given in place.
    cv::Mat row;
    for (int r = 0; ok && r < image.rows; ++r) {
      row = channels == 1 ? image.row(r).clone() : SwapRedAndBlue(image.row(r), channels);
      ok = TIFFWriteScanline(t, row.ptr(), static_cast<std::uint32_t>(r), 0) == 1;
    }
    if (!ok || !TIFFFlush(t)) {
      *why = Reason(stream, "cannot write the image");
      return false;
    }
  }
  out->insert(out->end(), stream.written.begin(), stream.written.end());
  return true;
}

}  // namespace photorig::solvers::codecs::internal
