#include "arrays.h"

#include <cstring>
#include <string>

namespace photorig::python {

namespace {

py::dtype DtypeOf(int depth) {
  switch (depth) {
    case CV_8U: return py::dtype::of<std::uint8_t>();
    case CV_8S: return py::dtype::of<std::int8_t>();
    case CV_16U: return py::dtype::of<std::uint16_t>();
    case CV_16S: return py::dtype::of<std::int16_t>();
    case CV_32S: return py::dtype::of<std::int32_t>();
    case CV_32F: return py::dtype::of<float>();
    case CV_64F: return py::dtype::of<double>();
    default: throw py::type_error("no NumPy dtype for OpenCV depth " + std::to_string(depth));
  }
}

}  // namespace

py::array ToArray(const cv::Mat& mat) {
  if (mat.empty()) return py::array(py::dtype::of<float>(), std::vector<py::ssize_t>{0, 0});
  // The capsule owns a reference to the pixels; the array keeps the capsule.
  auto* owner = new cv::Mat(mat);
  py::capsule keep(owner, [](void* p) { delete static_cast<cv::Mat*>(p); });
  const py::ssize_t element = static_cast<py::ssize_t>(mat.elemSize1());
  std::vector<py::ssize_t> shape{mat.rows, mat.cols};
  std::vector<py::ssize_t> strides{static_cast<py::ssize_t>(mat.step[0]), static_cast<py::ssize_t>(mat.elemSize())};
  if (mat.channels() > 1) {
    shape.push_back(mat.channels());
    strides.push_back(element);
  }
  return py::array(DtypeOf(mat.depth()), shape, strides, owner->data, keep);
}

py::array StackToArray(const std::vector<cv::Mat>& frames) {
  if (frames.empty()) return py::array(py::dtype::of<std::uint16_t>(), std::vector<py::ssize_t>{0, 0, 0});
  const cv::Mat& first = frames.front();
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(frames.size()), first.rows, first.cols};
  if (first.channels() > 1) shape.push_back(first.channels());
  py::array stack(DtypeOf(first.depth()), shape);
  const std::size_t bytes = first.total() * first.elemSize();
  auto* out = static_cast<std::uint8_t*>(stack.mutable_data());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const cv::Mat& frame = frames[i];
    if (frame.size() != first.size() || frame.type() != first.type() || !frame.isContinuous())
      throw py::value_error("frames differ in size or type");
    std::memcpy(out + i * bytes, frame.data, bytes);
  }
  return stack;
}

cv::Mat ViewAsMat(const py::array& array, int depth, const char* what) {
  const bool two_d = array.ndim() == 2;
  if (!(two_d || array.ndim() == 3) || !(array.flags() & py::array::c_style) ||
      !array.dtype().is(DtypeOf(depth)))
    throw py::value_error(std::string(what) + " must be a C-contiguous 2-D (rows, cols) or 3-D (rows, cols, channels) " +
                          std::string(py::str(DtypeOf(depth))) + " array");
  const int channels = two_d ? 1 : static_cast<int>(array.shape(2));
  if (channels < 1 || channels > CV_CN_MAX) throw py::value_error(std::string(what) + " has too many channels");
  return cv::Mat(static_cast<int>(array.shape(0)), static_cast<int>(array.shape(1)), CV_MAKETYPE(depth, channels),
                 const_cast<void*>(array.data()));
}

py::array_t<double> VectorsToArray(const std::vector<Eigen::Vector3d>& vectors) {
  py::array_t<double> out({static_cast<py::ssize_t>(vectors.size()), py::ssize_t{3}});
  auto view = out.mutable_unchecked<2>();
  for (std::size_t i = 0; i < vectors.size(); ++i)
    for (int k = 0; k < 3; ++k) view(i, k) = vectors[i][k];
  return out;
}

py::object ToPython(const nlohmann::json& value) {
  using Type = nlohmann::json::value_t;
  switch (value.type()) {
    case Type::null: return py::none();
    case Type::boolean: return py::bool_(value.get<bool>());
    case Type::number_integer: return py::int_(value.get<std::int64_t>());
    case Type::number_unsigned: return py::int_(value.get<std::uint64_t>());
    case Type::number_float: return py::float_(value.get<double>());
    case Type::string: return py::str(value.get_ref<const std::string&>());
    case Type::array: {
      py::list list;
      for (const nlohmann::json& item : value) list.append(ToPython(item));
      return list;
    }
    case Type::object: {
      py::dict dict;
      for (const auto& [key, item] : value.items()) dict[py::str(key)] = ToPython(item);
      return dict;
    }
    default: return py::none();  // binary and discarded values never come from our JSON
  }
}

}  // namespace photorig::python
