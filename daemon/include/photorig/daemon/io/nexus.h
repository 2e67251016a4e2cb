#pragma once
// NeXus files (HDF5). NexusWriter writes one group by group: groups carry their NX_class,
// datasets their units and attributes, and a frame stack is written one frame
// at a time into a chunked, deflate-compressed dataset. The HDF5 C library
// stays behind this header. Paths are absolute in the file ("/entry/sample").
//
// The file is written beside itself (PATH.partial) and renamed into place by
// Close(), so it appears whole or not at all. Errors do not throw: the first
// one is kept (naming the file and the path that failed) and every later call
// does nothing, so a writer is used straight through and checked once with
// ok() / error() after Close().

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace photorig::daemon {

struct NexusWriterOptions {
  // zlib level of the frame stack's chunks, 0 (stored) .. 9. Default 4:
  // 16-bit sensor frames compress little beyond it and writing slows down.
  int deflate_level = 4;
  // HDF5's byte shuffle before deflate: the high and low bytes of 16-bit
  // samples are compressed apart, which is what makes them compress. Default on.
  bool shuffle = true;

  bool IsValid(std::string* why) const;
};

class NexusWriter {
 public:
  // Creates (replaces) `path` with the file-level attributes NeXus asks for
  // (file_name, file_time, creator, HDF5_Version, default = `default_entry`).
  NexusWriter(const std::string& path, const std::string& creator, const std::string& default_entry,
              const NexusWriterOptions& options = {});
  ~NexusWriter();  // without Close() (an exception on the way), leaves no file
  NexusWriter(const NexusWriter&) = delete;
  NexusWriter& operator=(const NexusWriter&) = delete;

  // A group with its NX_class ("NXentry", ...); its parent must exist.
  void Group(const std::string& path, const std::string& nx_class);
  // Attributes of a group or dataset.
  void Attribute(const std::string& path, const std::string& name, const std::string& value);
  void Attribute(const std::string& path, const std::string& name, const std::vector<std::string>& values);
  void Attribute(const std::string& path, const std::string& name, double value);
  void Attribute(const std::string& path, const std::string& name, std::int64_t value);

  // Datasets: a UTF-8 string, a scalar, or an array of `dims` (row-major;
  // empty dims: one value). `units`, when not empty, becomes the units
  // attribute. No arrays of strings: the NeXus C API (nxdir, nxsummary)
  // crashes reading them.
  void Text(const std::string& path, const std::string& text);
  void Scalar(const std::string& path, double value, const std::string& units = "");
  void Doubles(const std::string& path, const std::vector<double>& values, const std::vector<std::uint64_t>& dims,
               const std::string& units = "");
  void Floats(const std::string& path, const float* values, const std::vector<std::uint64_t>& dims,
              const std::string& units = "");
  void Ints(const std::string& path, const std::vector<std::int64_t>& values, const std::string& units = "");
  void Integer(const std::string& path, std::int64_t value);

  // A stack of `frames` uint16 images of `frame_dims` (rows, columns[,
  // channels]), chunked one frame per chunk; fill it with WriteFrame.
  void BeginFrameStack(const std::string& path, std::uint64_t frames, const std::vector<std::uint64_t>& frame_dims);
  void WriteFrame(std::uint64_t index, const std::uint16_t* samples);

  // A second name for an existing object (HDF5 hard link).
  void Link(const std::string& target, const std::string& link_path);

  // Closes the file and puts it in place; false (with error()), and no file,
  // if anything failed.
  bool Close();
  // Ends the writing with `why` as the error, leaving no file.
  void Abandon(const std::string& why);
  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }

 private:
  struct Handles;
  std::string Partial() const;
  bool Failed(const std::string& what);  // records the first error; returns false
  void StringAttribute(const std::string& path, const std::string& name, bool scalar,
                       const std::vector<std::string>& values);
  // `file_type` is an HDF5 type id (hid_t): H5T_IEEE_F64LE, H5T_IEEE_F32LE or H5T_STD_I64LE.
  void NumberAttribute(const std::string& path, const std::string& name, std::int64_t file_type, const void* value);
  void Numbers(const std::string& path, std::int64_t file_type, const void* values,
               const std::vector<std::uint64_t>& dims, const std::string& units);

  std::string path_;
  NexusWriterOptions options_;
  std::unique_ptr<Handles> handles_;
  std::string error_;
};

// Reads the string dataset `dataset` ("/entry/ps/version") of a NeXus file
// into *text; false with *error naming the file and what is missing.
bool ReadNexusText(const std::string& file, const std::string& dataset, std::string* text, std::string* error);

}  // namespace photorig::daemon
