#pragma once
// Which image format a file's first bytes say it is, for the formats the
// project reads. OpenCV picks a decoder by the first signature that matches,
// and the DICOM decoder it may be built with (GDCM) takes any file with
// "DICM" at byte 128 and aborts the process on a malformed one (an assert in
// Debian's build). A reader that decodes only what this names, each format
// checked before DICOM in OpenCV's order, keeps a stray or hostile file an
// error instead of a crash.

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace photorig::solvers::core {

enum class ImageFileFormat { kUnknown, kPng, kTiff, kJpeg, kBmp, kPnm, kRadianceHdr };

// The format whose signature `head` (a file's first bytes; 16 are enough)
// begins with; kUnknown for anything else, OpenEXR, JPEG 2000 and DICOM among them.
ImageFileFormat ImageFileFormatOf(std::span<const std::uint8_t> head);

// The formats named above, for messages: "PNG, TIFF, JPEG, BMP, PNM or Radiance HDR".
const char* ReadableImageFormats();

// Largest image file read: past 1 GiB (a 16-bit RGB image of 170 megapixels
// stored raw) it is not a frame this project reads, and the file is read
// whole before it is decoded.
inline constexpr std::uintmax_t kMaxImageFileBytes = std::uintmax_t{1} << 30;

// The bytes of an image file ready to decode: a regular file of at most
// kMaxImageFileBytes whose first bytes name a readable format. Otherwise
// false, and `why` says which (missing, not a regular file, its size, a read
// error, not one of the formats).
bool ReadImageFileBytes(const std::string& path, std::vector<std::uint8_t>* bytes, std::string* why);

}  // namespace photorig::solvers::core
