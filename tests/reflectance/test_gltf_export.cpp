// The glTF asset loads back with tinygltf, and a render of what it holds
// (its mesh, normals and textures, shaded with glTF's BRDF at the camera view)
// matches the relit image of the fitted reflectance.
#include "photorig/daemon/io/gltf_export.h"
#include "photorig/solvers/reflectance/gltf_material.h"
#include "svbrdf_scene.h"

#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <filesystem>

namespace photorig::testing {
namespace {

namespace fs = std::filesystem;

double FromSrgb(double s) { return s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4); }

template <typename T>
const T* AccessorData(const tinygltf::Model& model, int accessor) {
  const tinygltf::Accessor& a = model.accessors[accessor];
  const tinygltf::BufferView& v = model.bufferViews[a.bufferView];
  return reinterpret_cast<const T*>(model.buffers[v.buffer].data.data() + v.byteOffset + a.byteOffset);
}

cv::Mat ReadRgb(const fs::path& path) {
  cv::Mat bgr = cv::imread(path.string(), cv::IMREAD_COLOR), rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

TEST(GltfExport, TheAssetLoadsBackAndRendersLikeTheFit) {
  const SvbrdfScene scene = MakeScene(ThreeMaterials());
  const refl::ReflectanceMaps& maps = scene.truth;
  // The sphere's height as the depth (any finite depth gives the same shading at the camera view).
  cv::Mat depth(maps.normals.size(), CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c)
      if (scene.mask.at<std::uint8_t>(r, c)) depth.at<float>(r, c) = maps.normals.at<cv::Vec3f>(r, c)[2];
  const fs::path dir = fs::temp_directory_path() / ("gltf_export_" + std::to_string(::getpid()));
  const daemon::GltfExport written = daemon::WriteGltfAsset(
      dir.string(), maps, depth, solvers::camera::PixelRays(solvers::camera::Camera::Orthographic(depth.cols, depth.rows, 1.0)));
  EXPECT_EQ(written.vertices, static_cast<std::size_t>(cv::countNonZero(scene.mask)));
  EXPECT_GT(written.triangles, written.vertices);

  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string error, warning;
  ASSERT_TRUE(loader.LoadASCIIFromFile(&model, &error, &warning, written.gltf_path)) << error;
  ASSERT_EQ(model.meshes.size(), 1u);
  const tinygltf::Primitive& primitive = model.meshes[0].primitives.at(0);
  const int vertices = static_cast<int>(model.accessors[primitive.attributes.at("POSITION")].count);
  ASSERT_EQ(static_cast<std::size_t>(vertices), written.vertices);
  const float* position = AccessorData<float>(model, primitive.attributes.at("POSITION"));
  const float* normal = AccessorData<float>(model, primitive.attributes.at("NORMAL"));
  const float* uv = AccessorData<float>(model, primitive.attributes.at("TEXCOORD_0"));
  const tinygltf::Material& material = model.materials.at(primitive.material);
  auto texture_path = [&](int texture) { return dir / model.images[model.textures[texture].source].uri; };
  const cv::Mat base = ReadRgb(texture_path(material.pbrMetallicRoughness.baseColorTexture.index));
  const cv::Mat mr = ReadRgb(texture_path(material.pbrMetallicRoughness.metallicRoughnessTexture.index));
  const tinygltf::Value& specular = material.extensions.at("KHR_materials_specular");
  const cv::Mat spec = ReadRgb(texture_path(specular.Get("specularColorTexture").Get("index").GetNumberAsInt()));
  const double spec_factor = specular.Get("specularColorFactor").Get(0).GetNumberAsDouble();

  const Eigen::Vector3d view = Eigen::Vector3d::UnitZ();
  for (const Eigen::Vector3d& light : {Eigen::Vector3d(0.3, 0.2, 0.93).normalized(), Eigen::Vector3d(-0.6, 0.1, 0.79).normalized()}) {
    cv::Mat relit;
    ASSERT_TRUE(refl::RenderReflectance(maps, light, Eigen::Vector3d::Ones(), view, &relit).IsSolutionUsable());
    double diff_file = 0.0, diff_fit = 0.0, norm = 0.0;
    for (int v = 0; v < vertices; ++v) {
      // The dome's frame: x right and y up from the image's centre, 1 mm a pixel.
      const int c = static_cast<int>(std::floor(position[3 * v] + 0.5 * depth.cols));
      const int r = static_cast<int>(std::floor(0.5 * depth.rows - position[3 * v + 1]));
      const int tc = static_cast<int>(uv[2 * v] * base.cols), tr = static_cast<int>(uv[2 * v + 1] * base.rows);
      ASSERT_EQ(tc, c);
      ASSERT_EQ(tr, r);
      const Eigen::Vector3d n(normal[3 * v], normal[3 * v + 1], normal[3 * v + 2]);
      refl::GltfMaterial g;
      g.roughness = mr.at<cv::Vec3b>(tr, tc)[1] / 255.0;
      Eigen::Vector3d colour;
      for (int ch = 0; ch < 3; ++ch) {
        colour[ch] = FromSrgb(base.at<cv::Vec3b>(tr, tc)[ch] / 255.0);
        g.specular_colour[ch] = spec.at<cv::Vec3b>(tr, tc)[ch] / 255.0 * spec_factor;
      }
      // The frame of the normal, as the solver's renderer builds it.
      const Eigen::Vector3d a = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
      const Eigen::Vector3d t = a.cross(n).normalized(), b = n.cross(t);
      const Eigen::Vector3d wi(t.dot(light), b.dot(light), n.dot(light)), wo(t.dot(view), b.dot(view), n.dot(view));
      const Eigen::Vector3d from_file = refl::EvaluateGltf(colour, g, wi, wo) * std::max(0.0, wi.z());
      // The same glTF BRDF with the exact (unquantised) parameters.
      const refl::MaterialFit& fit = maps.materials[maps.material.at<std::uint8_t>(r, c)];
      const cv::Vec3f exact_albedo = maps.albedo.at<cv::Vec3f>(r, c);
      const refl::GltfMaterial exact = refl::ToGltf(fit);
      Eigen::Vector3d exact_base;
      for (int ch = 0; ch < 3; ++ch) exact_base[ch] = refl::GltfBaseColour(exact_albedo[ch], exact, ch);
      const Eigen::Vector3d from_fit = refl::EvaluateGltf(exact_base, exact, wi, wo) * std::max(0.0, wi.z());
      const cv::Vec3f target = relit.at<cv::Vec3f>(r, c);
      for (int ch = 0; ch < 3; ++ch) {
        diff_file += std::pow(from_file[ch] - from_fit[ch], 2);
        diff_fit += std::pow(from_file[ch] - target[ch], 2);
        norm += target[ch] * target[ch];
      }
    }
    const double file_error = std::sqrt(diff_file / norm), relit_error = std::sqrt(diff_fit / norm);
    std::printf("light (%.2f, %.2f, %.2f): glTF file vs exact glTF %.4f, glTF render vs relit %.4f\n", light.x(),
                light.y(), light.z(), file_error, relit_error);
    // 8-bit textures: within 2 %.
    EXPECT_LT(file_error, 0.02);
    // The mapping to glTF's model (docs/reflectance.md): exact for GGX, about
    // 15 % for the Blinn-Phong band, whose lobe GGX only approximates.
    EXPECT_LT(relit_error, 0.2);
  }
  fs::remove_all(dir);
}

TEST(GltfExport, TheMappingErrorIsSmallForGgxAndStatedForBlinnPhong) {
  const auto lights = DomeLights();
  EXPECT_EQ(refl::GltfMappingError(Matte(), lights, Eigen::Vector3d::UnitZ()), 0.0);
  const double ggx = refl::GltfMappingError(Ggx(0.25, 0.3), lights, Eigen::Vector3d::UnitZ());
  const double phong = refl::GltfMappingError(Phong(0.35, 80.0), lights, Eigen::Vector3d::UnitZ());
  std::printf("glTF mapping error: GGX %.4f, Blinn-Phong %.4f\n", ggx, phong);
  EXPECT_GT(ggx, 0.0);
  EXPECT_LT(ggx, 0.1);
  EXPECT_LT(phong, 0.3);
}

}  // namespace
}  // namespace photorig::testing
