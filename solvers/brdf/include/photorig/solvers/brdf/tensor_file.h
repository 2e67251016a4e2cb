#pragma once
// The tensor_file container of Mitsuba and the EPFL RGL material database
// (`.bsdf` files): named n-dimensional arrays in one little-endian file.
//
//   12 bytes  "tensor_file\0"
//    2 bytes  version: major, minor (1, 0)
//    4 bytes  uint32 field count
//   per field: uint16 name length, the name, uint16 ndim, uint8 dtype,
//              uint64 offset of the data from the start of the file,
//              ndim x uint64 shape (last dimension contiguous)
//   the fields' data, each at its offset
//
// dtype is Mitsuba's Struct::Type: 1 uint8, 2 int8, 3 uint16, 4 int16,
// 5 uint32, 6 int32, 7 uint64, 8 int64, 9 float16, 10 float32, 11 float64.

#include "photorig/solvers/core/summary.h"

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace photorig::solvers::brdf {

enum class TensorType : std::uint8_t {
  kUInt8 = 1, kInt8, kUInt16, kInt16, kUInt32, kInt32, kUInt64, kInt64, kFloat16, kFloat32, kFloat64
};
const char* TensorTypeName(TensorType type);  // "uint8", ..., "float64"
std::size_t TensorTypeBytes(TensorType type);

struct TensorField {
  std::string name;
  TensorType type = TensorType::kFloat32;
  std::vector<std::uint64_t> shape;
  std::vector<std::uint8_t> bytes;  // the data as stored (little-endian)

  std::size_t Count() const;  // product of the shape (1 for ndim 0)
  // Float32 data as floats (the caller has checked the type).
  std::vector<float> Floats() const;
  static TensorField FromFloats(std::string name, std::vector<std::uint64_t> shape, const std::vector<float>& values);
  static TensorField FromBytes(std::string name, std::vector<std::uint64_t> shape, std::vector<std::uint8_t> bytes);
};

struct TensorFile {
  std::vector<TensorField> fields;  // in file order; names are unique
  const TensorField* Find(std::string_view name) const;
};

inline constexpr std::uint8_t kTensorFileVersion[2] = {1, 0};

// The largest tensor file ReadTensorFile reads: the RGL tables are a few MiB.
inline constexpr std::uint64_t kMaxTensorFileBytes = std::uint64_t{256} << 20;

// Reads a tensor file. Never throws: a missing or truncated file, one that
// is not a regular file or is larger than kMaxTensorFileBytes, a wrong
// magic or version, an unknown dtype, a field whose data lies outside the file
// or a repeated field name ends kInvalidInput with a message naming the file
// and the fault; `file` is then untouched.
core::Summary ReadTensorFile(const std::string& path, TensorFile* file);

// Writes `file` (fields in order, data after the headers, 8-byte aligned).
core::Summary WriteTensorFile(const std::string& path, const TensorFile& file);

}  // namespace photorig::solvers::brdf
