#pragma once
// Triangle meshes from depth maps, as binary little-endian PLY.

#include "photorig/solvers/camera/camera.h"

#include <opencv2/core.hpp>

#include <functional>

#include <string>

namespace photorig::daemon {

// One vertex per finite depth pixel at (x, y, z) = ((c + 0.5) p, -(r + 0.5) p, depth)
// with p the pixel pitch (y up, as the normals), two triangles per 2x2 block of
// finite pixels, wound counter-clockwise seen from the camera. Written durably.
// Returns the number of triangles.
std::size_t WriteDepthMeshPly(const std::string& path, const cv::Mat& depth, double pixel_pitch);
// The same for a height map seen through a pinhole camera: each vertex where
// its pixel's line of sight reaches that height, in the camera's frame
// (solvers/camera/camera.h), so the mesh keeps the object's true shape.
std::size_t WriteDepthMeshPly(const std::string& path, const cv::Mat& height_mm, const solvers::camera::PixelRays& rays);

}  // namespace photorig::daemon
