#include "photorig/daemon/io/nexus.h"
#include "photorig/daemon/io/utc_time.h"
#include "photorig/solvers/core/summary.h"

#include <hdf5.h>

#include <chrono>
#include <ctime>
#include <filesystem>

namespace photorig::daemon {
using solvers::core::Refuse;

namespace {

// A variable-length UTF-8 string type: h5py reads it as str, silx shows it as text.
hid_t StringType() {
  const hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, H5T_VARIABLE);
  H5Tset_cset(type, H5T_CSET_UTF8);
  return type;
}

std::vector<hsize_t> Dims(const std::vector<std::uint64_t>& dims) { return {dims.begin(), dims.end()}; }

// The native type that holds in memory what is stored as `file_type`.
hid_t NativeTypeOf(hid_t file_type) {
  if (file_type == H5T_IEEE_F64LE) return H5T_NATIVE_DOUBLE;
  return file_type == H5T_IEEE_F32LE ? H5T_NATIVE_FLOAT : H5T_NATIVE_INT64;
}

// Closes an HDF5 handle of any kind when it goes out of scope.
struct Handle {
  hid_t id;
  explicit Handle(hid_t id) : id(id) {}
  ~Handle() {
    if (id >= 0) H5Idec_ref(id);
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
};

}  // namespace

bool NexusWriterOptions::IsValid(std::string* why) const {
  if (deflate_level < 0 || deflate_level > 9) return Refuse(why, "deflate_level must be within [0, 9]");
  return true;
}

struct NexusWriter::Handles {
  hid_t file = -1;
  hid_t stack = -1;  // the frame stack being filled
  std::vector<hsize_t> stack_dims;
};

NexusWriter::NexusWriter(const std::string& path, const std::string& creator, const std::string& default_entry,
                         const NexusWriterOptions& options)
    : path_(path), options_(options), handles_(std::make_unique<Handles>()) {
  // Errors come back as error(); HDF5's own stack dump on stderr would only repeat them.
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  if (std::string why; !options.IsValid(&why)) {
    Failed("NexusWriterOptions: " + why);
    return;
  }
  handles_->file = H5Fcreate(Partial().c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (handles_->file < 0) {
    Failed("cannot create the file (does its folder exist, and may it be written?)");
    return;
  }
  unsigned major = 0, minor = 0, release = 0;
  H5get_libversion(&major, &minor, &release);
  Attribute("/", "file_name", std::filesystem::path(path).filename().string());
  Attribute("/", "file_time", UtcNowIso8601());
  Attribute("/", "creator", creator);
  Attribute("/", "HDF5_Version", std::to_string(major) + "." + std::to_string(minor) + "." + std::to_string(release));
  Attribute("/", "default", default_entry);
}

NexusWriter::~NexusWriter() {
  if (handles_->file >= 0) Abandon("the writing stopped before Close()");
}

std::string NexusWriter::Partial() const { return path_ + ".partial"; }

bool NexusWriter::Failed(const std::string& what) {
  if (error_.empty()) error_ = path_ + ": " + what;
  return false;
}

void NexusWriter::Group(const std::string& path, const std::string& nx_class) {
  if (!ok()) return;
  const Handle group(H5Gcreate2(handles_->file, path.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  if (group.id < 0) {
    Failed("cannot create group " + path);
    return;
  }
  Attribute(path, "NX_class", nx_class);
}

void NexusWriter::StringAttribute(const std::string& path, const std::string& name, bool scalar,
                                  const std::vector<std::string>& values) {
  if (!ok()) return;
  const hsize_t count = values.size();
  const Handle type(StringType()), space(scalar ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &count, nullptr));
  const Handle attribute(H5Acreate_by_name(handles_->file, path.c_str(), name.c_str(), type.id, space.id, H5P_DEFAULT,
                                           H5P_DEFAULT, H5P_DEFAULT));
  std::vector<const char*> texts;
  for (const std::string& value : values) texts.push_back(value.c_str());
  if (attribute.id < 0 || H5Awrite(attribute.id, type.id, texts.data()) < 0)
    Failed("cannot write attribute " + name + " of " + path);
}

// One string is a scalar attribute, as NeXus readers expect (NX_class, signal, units).
void NexusWriter::Attribute(const std::string& path, const std::string& name, const std::string& value) {
  StringAttribute(path, name, true, {value});
}

void NexusWriter::Attribute(const std::string& path, const std::string& name, const std::vector<std::string>& values) {
  StringAttribute(path, name, false, values);
}

void NexusWriter::Attribute(const std::string& path, const std::string& name, double value) {
  NumberAttribute(path, name, H5T_IEEE_F64LE, &value);
}

void NexusWriter::Attribute(const std::string& path, const std::string& name, std::int64_t value) {
  NumberAttribute(path, name, H5T_STD_I64LE, &value);
}

void NexusWriter::NumberAttribute(const std::string& path, const std::string& name, std::int64_t file_type,
                                  const void* value) {
  const hid_t type = file_type;
  if (!ok()) return;
  const Handle space(H5Screate(H5S_SCALAR));
  const Handle attribute(H5Acreate_by_name(handles_->file, path.c_str(), name.c_str(), type, space.id, H5P_DEFAULT,
                                           H5P_DEFAULT, H5P_DEFAULT));
  if (attribute.id < 0 || H5Awrite(attribute.id, NativeTypeOf(type), value) < 0)
    Failed("cannot write attribute " + name + " of " + path);
}

void NexusWriter::Text(const std::string& path, const std::string& text) {
  if (!ok()) return;
  const Handle type(StringType()), space(H5Screate(H5S_SCALAR));
  const Handle dataset(H5Dcreate2(handles_->file, path.c_str(), type.id, space.id, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  const char* data = text.c_str();
  if (dataset.id < 0 || H5Dwrite(dataset.id, type.id, H5S_ALL, H5S_ALL, H5P_DEFAULT, &data) < 0)
    Failed("cannot write " + path);
}

void NexusWriter::Numbers(const std::string& path, std::int64_t file_type, const void* values,
                          const std::vector<std::uint64_t>& dims, const std::string& units) {
  const hid_t type = file_type;
  if (!ok()) return;
  const std::vector<hsize_t> shape = Dims(dims);
  const Handle space(shape.empty() ? H5Screate(H5S_SCALAR)
                                   : H5Screate_simple(static_cast<int>(shape.size()), shape.data(), nullptr));
  const Handle dataset(H5Dcreate2(handles_->file, path.c_str(), type, space.id, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  if (dataset.id < 0 || H5Dwrite(dataset.id, NativeTypeOf(type), H5S_ALL, H5S_ALL, H5P_DEFAULT, values) < 0) {
    Failed("cannot write " + path);
    return;
  }
  if (!units.empty()) Attribute(path, "units", units);
}

void NexusWriter::Scalar(const std::string& path, double value, const std::string& units) {
  Numbers(path, H5T_IEEE_F64LE, &value, {}, units);
}

void NexusWriter::Doubles(const std::string& path, const std::vector<double>& values,
                          const std::vector<std::uint64_t>& dims, const std::string& units) {
  Numbers(path, H5T_IEEE_F64LE, values.data(), dims, units);
}

void NexusWriter::Floats(const std::string& path, const float* values, const std::vector<std::uint64_t>& dims,
                         const std::string& units) {
  Numbers(path, H5T_IEEE_F32LE, values, dims, units);
}

void NexusWriter::Ints(const std::string& path, const std::vector<std::int64_t>& values, const std::string& units) {
  Numbers(path, H5T_STD_I64LE, values.data(), {values.size()}, units);
}

void NexusWriter::Integer(const std::string& path, std::int64_t value) {
  Numbers(path, H5T_STD_I64LE, &value, {}, "");
}

void NexusWriter::BeginFrameStack(const std::string& path, std::uint64_t frames,
                                  const std::vector<std::uint64_t>& frame_dims) {
  if (!ok()) return;
  if (handles_->stack >= 0) H5Dclose(handles_->stack);
  handles_->stack_dims = {frames};
  for (std::uint64_t dim : frame_dims) handles_->stack_dims.push_back(dim);
  std::vector<hsize_t> chunk = handles_->stack_dims;
  chunk[0] = 1;
  const Handle space(H5Screate_simple(static_cast<int>(handles_->stack_dims.size()), handles_->stack_dims.data(), nullptr));
  const Handle properties(H5Pcreate(H5P_DATASET_CREATE));
  H5Pset_chunk(properties.id, static_cast<int>(chunk.size()), chunk.data());
  if (options_.shuffle) H5Pset_shuffle(properties.id);
  H5Pset_deflate(properties.id, static_cast<unsigned>(options_.deflate_level));
  handles_->stack =
      H5Dcreate2(handles_->file, path.c_str(), H5T_STD_U16LE, space.id, H5P_DEFAULT, properties.id, H5P_DEFAULT);
  if (handles_->stack < 0) Failed("cannot create the frame stack " + path);
}

void NexusWriter::WriteFrame(std::uint64_t index, const std::uint16_t* samples) {
  if (!ok()) return;
  if (handles_->stack < 0 || index >= handles_->stack_dims[0]) {
    Failed("frame " + std::to_string(index) + " lies outside the frame stack");
    return;
  }
  std::vector<hsize_t> start(handles_->stack_dims.size(), 0), count = handles_->stack_dims;
  start[0] = index;
  count[0] = 1;
  const Handle file_space(H5Dget_space(handles_->stack));
  H5Sselect_hyperslab(file_space.id, H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr);
  const Handle memory_space(H5Screate_simple(static_cast<int>(count.size()), count.data(), nullptr));
  if (H5Dwrite(handles_->stack, H5T_NATIVE_UINT16, memory_space.id, file_space.id, H5P_DEFAULT, samples) < 0)
    Failed("cannot write frame " + std::to_string(index) + " (is the disk full?)");
}

void NexusWriter::Link(const std::string& target, const std::string& link_path) {
  if (!ok()) return;
  if (H5Lcreate_hard(handles_->file, target.c_str(), handles_->file, link_path.c_str(), H5P_DEFAULT, H5P_DEFAULT) < 0)
    Failed("cannot link " + link_path + " to " + target);
}

bool NexusWriter::Close() {
  if (handles_->stack >= 0) H5Dclose(handles_->stack);
  handles_->stack = -1;
  if (handles_->file < 0) return ok();
  if (H5Fclose(handles_->file) < 0) Failed("cannot close the file (is the disk full?)");
  handles_->file = -1;
  std::error_code error;
  if (ok()) std::filesystem::rename(Partial(), path_, error);
  if (error) Failed("cannot put the file in place: " + error.message());
  if (!ok()) std::filesystem::remove(Partial(), error);
  return ok();
}

void NexusWriter::Abandon(const std::string& why) {
  Failed(why);
  Close();
}

bool ReadNexusText(const std::string& file, const std::string& dataset, std::string* text, std::string* error) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const Handle opened(H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
  if (opened.id < 0) {
    *error = "cannot open " + file + " as HDF5";
    return false;
  }
  const Handle data(H5Dopen2(opened.id, dataset.c_str(), H5P_DEFAULT));
  const Handle stored(data.id < 0 ? -1 : H5Dget_type(data.id));
  if (data.id < 0 || H5Tget_class(stored.id) != H5T_STRING || !H5Tis_variable_str(stored.id)) {
    *error = file + " has no text " + dataset;
    return false;
  }
  const Handle type(StringType());
  char* value = nullptr;
  if (H5Dread(data.id, type.id, H5S_ALL, H5S_ALL, H5P_DEFAULT, &value) < 0 || value == nullptr) {
    *error = "cannot read " + dataset + " of " + file;
    return false;
  }
  *text = value;
  H5free_memory(value);
  return true;
}

}  // namespace photorig::daemon
