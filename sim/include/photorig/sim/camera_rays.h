#pragma once
// Many rays of a CameraModel at once: undistorting is cheaper by the batch,
// which renderers that sample each pixel several times need.

#include <Eigen/Core>

#include <vector>

namespace photorig::sim {

struct CameraModel;  // camera_model.h, whose Ray is this for one pixel

// The rays through points of the image, (x, y) in pixels from its top-left
// corner (pixel (col, row)'s centre is (col + 0.5, row + 0.5)): origins and
// unit directions, as CameraModel::Ray gives them for pixel centres.
void CameraRays(const CameraModel& camera, const std::vector<Eigen::Vector2d>& points_px,
                std::vector<Eigen::Vector3d>* origins, std::vector<Eigen::Vector3d>* directions);

}  // namespace photorig::sim
