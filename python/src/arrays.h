#pragma once
// OpenCV matrices <-> NumPy arrays. An array made from a cv::Mat shares its
// pixels (the array holds a reference to the Mat), so nothing is copied.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <vector>

namespace photorig::python {

namespace py = pybind11;

// (rows, cols) for one channel, (rows, cols, channels) for more; the Mat's
// depth as the dtype. Shares `mat`'s buffer.
py::array ToArray(const cv::Mat& mat);

// Frames of one size and type as one (count, rows, cols[, channels]) array.
py::array StackToArray(const std::vector<cv::Mat>& frames);

// A C-contiguous array (2-D, or 3-D for channels) of `depth` viewed as a
// cv::Mat without a copy; the array must outlive the Mat. Throws
// ValueError naming `what` for another shape.
cv::Mat ViewAsMat(const py::array& array, int depth, const char* what);

// (n, 3) double array of vectors.
py::array_t<double> VectorsToArray(const std::vector<Eigen::Vector3d>& vectors);

// JSON as Python objects (dict, list, str, int, float, bool, None).
py::object ToPython(const nlohmann::json& value);

}  // namespace photorig::python
