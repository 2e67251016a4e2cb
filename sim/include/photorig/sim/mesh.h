#pragma once
// Triangle meshes from PLY files, rasterised orthographically into the
// per-pixel geometry the renderer shades.

#include "photorig/sim/camera_model.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::sim {

struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;  // mm, object frame
  std::vector<Eigen::Vector3i> faces;     // indices into vertices; polygons are fanned into triangles
};

// Reads `element vertex` (x, y, z of any PLY scalar type) and `element face`
// (a list property of vertex indices) from ASCII or binary little-endian PLY;
// other elements and properties are skipped. Throws std::runtime_error naming
// the file and what is wrong.
TriangleMesh LoadPly(const std::string& path);
void SavePly(const std::string& path, const TriangleMesh& mesh, bool binary);

// Z-buffer rasterisation at pixel centres: `height` (CV_32F, z of the nearest
// surface towards the camera, NaN where no triangle covers the pixel) and
// `normals` (CV_32FC3, the covering face's normal turned towards the camera).
void RasterizeOrthographic(const TriangleMesh& mesh, const CameraModel& camera, cv::Mat* height, cv::Mat* normals);

}  // namespace photorig::sim
