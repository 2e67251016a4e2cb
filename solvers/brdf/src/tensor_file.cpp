#include "photorig/solvers/brdf/tensor_file.h"

#include <algorithm>
#include <bit>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <set>

namespace photorig::solvers::brdf {
namespace fs = std::filesystem;

// Fields are copied as raw little-endian bytes.
static_assert(std::endian::native == std::endian::little);

namespace {

constexpr char kMagic[12] = {'t', 'e', 'n', 's', 'o', 'r', '_', 'f', 'i', 'l', 'e', '\0'};

// Reads the header fields in order and says where it ran out.
class Cursor {
 public:
  explicit Cursor(const std::vector<std::uint8_t>& bytes) : bytes_(bytes) {}
  template <typename T>
  bool Read(T* value) {
    if (bytes_.size() - pos_ < sizeof(T)) return false;
    std::memcpy(value, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  bool ReadString(std::size_t length, std::string* out) {
    if (bytes_.size() - pos_ < length) return false;
    out->assign(reinterpret_cast<const char*>(bytes_.data() + pos_), length);
    pos_ += length;
    return true;
  }
  std::size_t pos() const { return pos_; }

 private:
  const std::vector<std::uint8_t>& bytes_;
  std::size_t pos_ = 0;
};

bool KnownType(std::uint8_t dtype) { return dtype >= 1 && dtype <= 11; }

}  // namespace

const char* TensorTypeName(TensorType type) {
  switch (type) {
    case TensorType::kUInt8: return "uint8";
    case TensorType::kInt8: return "int8";
    case TensorType::kUInt16: return "uint16";
    case TensorType::kInt16: return "int16";
    case TensorType::kUInt32: return "uint32";
    case TensorType::kInt32: return "int32";
    case TensorType::kUInt64: return "uint64";
    case TensorType::kInt64: return "int64";
    case TensorType::kFloat16: return "float16";
    case TensorType::kFloat32: return "float32";
    case TensorType::kFloat64: return "float64";
  }
  return "unknown";
}

std::size_t TensorTypeBytes(TensorType type) {
  switch (type) {
    case TensorType::kUInt8:
    case TensorType::kInt8: return 1;
    case TensorType::kUInt16:
    case TensorType::kInt16:
    case TensorType::kFloat16: return 2;
    case TensorType::kUInt32:
    case TensorType::kInt32:
    case TensorType::kFloat32: return 4;
    case TensorType::kUInt64:
    case TensorType::kInt64:
    case TensorType::kFloat64: return 8;
  }
  return 0;
}

std::size_t TensorField::Count() const {
  std::size_t n = 1;
  for (std::uint64_t s : shape) n *= static_cast<std::size_t>(s);
  return n;
}

std::vector<float> TensorField::Floats() const {
  std::vector<float> values(bytes.size() / sizeof(float));
  std::memcpy(values.data(), bytes.data(), values.size() * sizeof(float));
  return values;
}

TensorField TensorField::FromFloats(std::string name, std::vector<std::uint64_t> shape,
                                    const std::vector<float>& values) {
  std::vector<std::uint8_t> bytes(values.size() * sizeof(float));
  std::memcpy(bytes.data(), values.data(), bytes.size());
  TensorField field = FromBytes(std::move(name), std::move(shape), std::move(bytes));
  field.type = TensorType::kFloat32;
  return field;
}

TensorField TensorField::FromBytes(std::string name, std::vector<std::uint64_t> shape,
                                   std::vector<std::uint8_t> bytes) {
  TensorField field;
  field.name = std::move(name);
  field.type = TensorType::kUInt8;
  field.shape = std::move(shape);
  field.bytes = std::move(bytes);
  return field;
}

const TensorField* TensorFile::Find(std::string_view name) const {
  for (const TensorField& f : fields)
    if (f.name == name) return &f;
  return nullptr;
}

core::Summary ReadTensorFile(const std::string& path, TensorFile* file) {
  core::SolveTimer timer;
  const std::string where = "tensor file '" + path + "': ";
  // Only a regular file of bounded size is read: a device or a pipe
  // (/dev/urandom) would be read until memory ran out.
  std::error_code error;
  const fs::file_status status = fs::status(path, error);
  if (!error && fs::exists(status) && !fs::is_regular_file(status))
    return core::Ended(core::Termination::kInvalidInput, where + "not a regular file (a device, pipe or folder); give a .bsdf file");
  const std::uintmax_t size = fs::file_size(path, error);
  if (error) return core::Ended(core::Termination::kInvalidInput, where + "cannot open the file: " + error.message());
  if (size > kMaxTensorFileBytes)
    return core::Ended(core::Termination::kInvalidInput, where + std::to_string(size) + " bytes, more than the " +
                                                 std::to_string(kMaxTensorFileBytes >> 20) +
                                                 " MiB this reader accepts (the largest RGL tables are a few MiB)");
  std::ifstream in(path, std::ios::binary);
  if (!in) return core::Ended(core::Termination::kInvalidInput, where + "cannot open the file");
  std::vector<std::uint8_t> bytes(size);
  in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(size));
  if (static_cast<std::uintmax_t>(in.gcount()) != size)
    return core::Ended(core::Termination::kInvalidInput, where + "read " + std::to_string(in.gcount()) + " of its " +
                                                 std::to_string(size) + " bytes (changed while read?)");
  Cursor cursor(bytes);
  char magic[12];
  std::uint8_t version[2];
  std::uint32_t n_fields = 0;
  if (!cursor.Read(&magic) || !cursor.Read(&version) || !cursor.Read(&n_fields))
    return core::Ended(core::Termination::kInvalidInput,
                 where + std::to_string(bytes.size()) + " bytes, shorter than the 18-byte header (truncated?)");
  if (std::memcmp(magic, kMagic, sizeof kMagic) != 0)
    return core::Ended(core::Termination::kInvalidInput, where + "wrong header: does not start with \"tensor_file\\0\"");
  if (version[0] != kTensorFileVersion[0] || version[1] != kTensorFileVersion[1])
    return core::Ended(core::Termination::kInvalidInput, where + "version " + std::to_string(version[0]) + "." +
                                                 std::to_string(version[1]) + ", this reader knows 1.0");
  TensorFile read;
  std::set<std::string> names;
  for (std::uint32_t i = 0; i < n_fields; ++i) {
    const std::string which = "field " + std::to_string(i + 1) + " of " + std::to_string(n_fields);
    std::uint16_t name_length = 0, ndim = 0;
    std::uint8_t dtype = 0;
    std::uint64_t offset = 0;
    TensorField field;
    if (!cursor.Read(&name_length) || !cursor.ReadString(name_length, &field.name) || !cursor.Read(&ndim) ||
        !cursor.Read(&dtype) || !cursor.Read(&offset))
      return core::Ended(core::Termination::kInvalidInput, where + "the header of " + which + " is cut short at byte " +
                                                   std::to_string(bytes.size()) + " (truncated?)");
    const std::string named = which + " '" + field.name + "'";
    if (!KnownType(dtype))
      return core::Ended(core::Termination::kInvalidInput, where + named + " has unknown dtype " + std::to_string(dtype));
    field.type = static_cast<TensorType>(dtype);
    // The product of the shape in bytes, refusing any overflow on the way:
    // a damaged header must not make the reader size gigabytes.
    std::uint64_t size_bytes = TensorTypeBytes(field.type);
    bool overflow = false;
    for (std::uint16_t d = 0; d < ndim; ++d) {
      std::uint64_t extent = 0;
      if (!cursor.Read(&extent))
        return core::Ended(core::Termination::kInvalidInput, where + "the shape of " + named + " is cut short (truncated?)");
      field.shape.push_back(extent);
      if (extent != 0 && size_bytes > std::numeric_limits<std::uint64_t>::max() / extent) overflow = true;
      size_bytes *= extent;
    }
    if (overflow || offset > bytes.size() || size_bytes > bytes.size() - offset)
      return core::Ended(core::Termination::kInvalidInput,
                   where + named + ": its data (" + (overflow ? std::string("more than 2^64") : std::to_string(size_bytes)) +
                       " bytes at offset " + std::to_string(offset) + ") lies beyond the end of the " +
                       std::to_string(bytes.size()) + "-byte file (short body or bad offset)");
    if (!names.insert(field.name).second)
      return core::Ended(core::Termination::kInvalidInput, where + "field '" + field.name + "' appears twice");
    field.bytes.assign(bytes.begin() + static_cast<std::ptrdiff_t>(offset),
                       bytes.begin() + static_cast<std::ptrdiff_t>(offset + size_bytes));
    read.fields.push_back(std::move(field));
  }
  *file = std::move(read);
  return timer.Succeeded();
}

core::Summary WriteTensorFile(const std::string& path, const TensorFile& file) {
  std::vector<std::uint8_t> header;
  auto put = [&header](const void* data, std::size_t n) {
    const auto* p = static_cast<const std::uint8_t*>(data);
    header.insert(header.end(), p, p + n);
  };
  put(kMagic, sizeof kMagic);
  put(kTensorFileVersion, 2);
  const auto n_fields = static_cast<std::uint32_t>(file.fields.size());
  put(&n_fields, 4);
  std::size_t header_bytes = header.size();
  for (const TensorField& f : file.fields) header_bytes += 2 + f.name.size() + 2 + 1 + 8 + 8 * f.shape.size();
  auto align8 = [](std::uint64_t n) { return (n + 7) / 8 * 8; };
  std::uint64_t offset = align8(header_bytes);
  for (const TensorField& f : file.fields) {
    const auto name_length = static_cast<std::uint16_t>(f.name.size());
    const auto ndim = static_cast<std::uint16_t>(f.shape.size());
    const auto dtype = static_cast<std::uint8_t>(f.type);
    put(&name_length, 2);
    put(f.name.data(), f.name.size());
    put(&ndim, 2);
    put(&dtype, 1);
    put(&offset, 8);
    put(f.shape.data(), 8 * f.shape.size());
    offset = align8(offset + f.bytes.size());
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return core::Ended(core::Termination::kInvalidInput, "cannot open '" + path + "' for writing");
  out.write(reinterpret_cast<const char*>(header.data()), static_cast<std::streamsize>(header.size()));
  std::uint64_t written = header.size();
  const char zeros[8] = {};
  for (const TensorField& f : file.fields) {
    out.write(zeros, static_cast<std::streamsize>(align8(written) - written));
    out.write(reinterpret_cast<const char*>(f.bytes.data()), static_cast<std::streamsize>(f.bytes.size()));
    written = align8(written) + f.bytes.size();
  }
  out.close();
  if (!out) return core::Ended(core::Termination::kFailure, "writing tensor file '" + path + "' failed");
  return core::Ended(core::Termination::kSuccess, "");
}

}  // namespace photorig::solvers::brdf
