#include "photorig/daemon/io/internal/mesh_io.h"

#include "photorig/daemon/io/image_io.h"

#include <cmath>
#include <cstring>
#include <vector>

namespace photorig::daemon {

namespace {

std::size_t WriteMeshPly(const std::string& path, const cv::Mat& depth,
                         const std::function<cv::Vec3f(int r, int c, float z)>& vertex_of) {
  CV_Assert(depth.type() == CV_32F);
  cv::Mat index(depth.size(), CV_32S, cv::Scalar(-1));
  std::vector<float> vertices;
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c) {
      const float z = depth.at<float>(r, c);
      if (!std::isfinite(z)) continue;
      index.at<int>(r, c) = static_cast<int>(vertices.size() / 3);
      const cv::Vec3f v = vertex_of(r, c, z);
      vertices.insert(vertices.end(), {v[0], v[1], v[2]});
    }
  std::vector<std::int32_t> faces;
  for (int r = 0; r + 1 < depth.rows; ++r)
    for (int c = 0; c + 1 < depth.cols; ++c) {
      const int a = index.at<int>(r, c), b = index.at<int>(r, c + 1);
      const int d = index.at<int>(r + 1, c), e = index.at<int>(r + 1, c + 1);
      if (a < 0 || b < 0 || d < 0 || e < 0) continue;
      // Row r+1 lies below row r, so (a, d, e) and (a, e, b) are counter-clockwise from +z.
      faces.insert(faces.end(), {a, d, e, a, e, b});
    }
  const std::size_t triangles = faces.size() / 3;
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment photorig depth mesh\nelement vertex " +
                       std::to_string(vertices.size() / 3) +
                       "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                       std::to_string(triangles) + "\nproperty list uchar int vertex_indices\nend_header\n";
  std::string bytes = header;
  bytes.append(reinterpret_cast<const char*>(vertices.data()), vertices.size() * sizeof(float));
  for (std::size_t f = 0; f < triangles; ++f) {
    bytes.push_back(static_cast<char>(3));
    bytes.append(reinterpret_cast<const char*>(&faces[3 * f]), 3 * sizeof(std::int32_t));
  }
  WriteFileDurably(path, bytes);
  return triangles;
}

}  // namespace

std::size_t WriteDepthMeshPly(const std::string& path, const cv::Mat& depth, double pixel_pitch) {
  return WriteMeshPly(path, depth, [pixel_pitch](int r, int c, float z) {
    return cv::Vec3f(float((c + 0.5) * pixel_pitch), float(-(r + 0.5) * pixel_pitch), z);
  });
}

std::size_t WriteDepthMeshPly(const std::string& path, const cv::Mat& height_mm, const solvers::camera::PixelRays& rays) {
  return WriteMeshPly(path, height_mm, [&rays](int r, int c, float z) {
    const Eigen::Vector3d p = rays.Point(r, c, z);
    return cv::Vec3f(float(p.x()), float(p.y()), float(p.z()));
  });
}

}  // namespace photorig::daemon
