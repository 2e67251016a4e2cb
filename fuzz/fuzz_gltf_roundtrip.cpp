// The glTF export round trip: bytes -> a small spatially varying reflectance
// (what FitReflectance hands WriteGltfAsset: 1 to 3 materials of any model,
// per-pixel albedo, unit normals, NaN where not fitted, a depth map with
// holes) -> the asset WriteGltfAsset writes, built in memory
// (internal::BuildGltfModel) -> tinygltf's JSON and back, in memory -> compared.
// The files are left out: writing them is one OpenCV or tinygltf call each,
// and tests/reflectance/test_gltf_export.cpp reads a written asset back from
// disk. The contract: a model that tinygltf serialises and loads, whose mesh
// has one vertex per fitted pixel with a finite depth at that pixel's place
// with its unit normal, whose triangles index those vertices only, whose
// images are the PNGs the asset writes, and whose roughness texture holds the
// materials' roughness; or std::runtime_error when no fitted pixel has a
// depth. Anything else aborts.
#include "gltf_model.h"
#include "photorig/solvers/reflectance/gltf_material.h"

#include <fuzzer/FuzzedDataProvider.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace {

namespace refl = photorig::solvers::reflectance;
namespace brdf = photorig::solvers::brdf;

void Check(bool holds, const char* what) {
  if (holds) return;
  std::fprintf(stderr, "glTF round trip: %s\n", what);
  std::abort();
}

// The float array behind an accessor (tightly packed, as the writer lays them out).
const float* Floats(const tinygltf::Model& model, int accessor, std::size_t components) {
  Check(accessor >= 0 && accessor < static_cast<int>(model.accessors.size()), "accessor index out of range");
  const tinygltf::Accessor& a = model.accessors[accessor];
  Check(a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT, "vertex attribute is not float");
  const tinygltf::BufferView& view = model.bufferViews.at(a.bufferView);
  const tinygltf::Buffer& buffer = model.buffers.at(view.buffer);
  Check(view.byteOffset + a.byteOffset + a.count * components * sizeof(float) <= buffer.data.size(),
        "accessor runs past its buffer");
  return reinterpret_cast<const float*>(buffer.data.data() + view.byteOffset + a.byteOffset);
}

float Unit(FuzzedDataProvider& in) { return in.ConsumeFloatingPointInRange<float>(-1.0f, 1.0f); }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  const int rows = in.ConsumeIntegralInRange(1, 6), cols = in.ConsumeIntegralInRange(1, 6);
  const int channels = in.ConsumeBool() ? 3 : 1;
  const double pixel_pitch = in.ConsumeFloatingPointInRange(1e-3, 10.0);

  refl::ReflectanceMaps maps;
  const int materials = in.ConsumeIntegralInRange(1, 3);
  for (int m = 0; m < materials; ++m) {
    refl::MaterialFit fit;
    fit.model = in.PickValueInArray({brdf::Model::kLambertian, brdf::Model::kBlinnPhong, brdf::Model::kGgx});
    for (int ch = 0; ch < 3; ++ch) fit.specular[ch] = in.ConsumeFloatingPointInRange(0.0, 4.0);
    fit.shape = fit.model == brdf::Model::kGgx ? in.ConsumeFloatingPointInRange(1e-3, 1.0)
                                                : in.ConsumeFloatingPointInRange(0.1, 1e4);
    maps.materials.push_back(fit);
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  maps.albedo = cv::Mat(rows, cols, CV_32FC(channels), cv::Scalar::all(nan));
  maps.material = cv::Mat(rows, cols, CV_8U, cv::Scalar(255));
  maps.normals = cv::Mat(rows, cols, CV_32FC3, cv::Scalar::all(nan));
  cv::Mat depth(rows, cols, CV_32F, cv::Scalar(nan));
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      if (in.ConsumeBool()) depth.at<float>(r, c) = in.ConsumeFloatingPointInRange(-1e4f, 1e4f);
      if (!in.ConsumeBool()) continue;  // not fitted
      maps.material.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(in.ConsumeIntegralInRange(0, materials - 1));
      for (int ch = 0; ch < channels; ++ch)
        maps.albedo.ptr<float>(r)[c * channels + ch] = in.ConsumeFloatingPointInRange(0.0f, 2.0f);
      cv::Vec3f n(Unit(in), Unit(in), Unit(in));
      const float length = static_cast<float>(cv::norm(n));
      maps.normals.at<cv::Vec3f>(r, c) = length > 1e-3f ? n / length : cv::Vec3f(0, 0, 1);
    }

  const photorig::solvers::camera::PixelRays rays(photorig::solvers::camera::Camera::Orthographic(cols, rows, pixel_pitch));
  photorig::daemon::internal::GltfModel written;
  try {
    written = photorig::daemon::internal::BuildGltfModel(maps, depth, rays);
  } catch (const std::runtime_error& e) {
    Check(std::strstr(e.what(), "no fitted pixel has a depth") != nullptr, e.what());
    return 0;
  }

  tinygltf::TinyGLTF gltf;
  std::ostringstream json;
  Check(gltf.WriteGltfSceneToStream(&written.model, json, false, false), "tinygltf cannot write the model");
  const std::string text = json.str();
  tinygltf::Model model;
  std::string error, warning;
  Check(gltf.LoadASCIIFromString(&model, &error, &warning, text.data(), static_cast<unsigned>(text.size()), ""),
        "tinygltf cannot load the asset");
  Check(model.meshes.size() == 1 && model.meshes[0].primitives.size() == 1, "not one mesh of one primitive");
  const tinygltf::Primitive& primitive = model.meshes[0].primitives[0];
  for (const char* attribute : {"POSITION", "NORMAL", "TEXCOORD_0"})
    Check(primitive.attributes.count(attribute) == 1, "an attribute is missing");

  // One vertex per fitted pixel with a finite depth, in row order.
  std::vector<std::array<float, 6>> expected;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const float z = depth.at<float>(r, c);
      if (maps.material.at<std::uint8_t>(r, c) >= maps.materials.size() || !std::isfinite(z)) continue;
      const cv::Vec3f n = maps.normals.at<cv::Vec3f>(r, c);
      // The dome's frame: x right and y up from the image's centre.
      expected.push_back({static_cast<float>((c + 0.5 - 0.5 * cols) * pixel_pitch),
                          static_cast<float>((0.5 * rows - r - 0.5) * pixel_pitch), z, n[0], n[1], n[2]});
    }
  Check(written.vertices == expected.size(), "vertex count reported wrong");
  const std::size_t vertices = expected.size();
  const tinygltf::Accessor& position_accessor = model.accessors.at(primitive.attributes.at("POSITION"));
  Check(position_accessor.count == vertices, "POSITION count is not the fitted pixels with depth");
  const float* positions = Floats(model, primitive.attributes.at("POSITION"), 3);
  const float* normals = Floats(model, primitive.attributes.at("NORMAL"), 3);
  const float* uvs = Floats(model, primitive.attributes.at("TEXCOORD_0"), 2);
  Check(model.accessors.at(primitive.attributes.at("NORMAL")).count == vertices, "NORMAL count differs");
  for (std::size_t v = 0; v < vertices; ++v) {
    for (int k = 0; k < 3; ++k) {
      Check(positions[3 * v + k] == expected[v][k], "a vertex is not at its pixel");
      Check(positions[3 * v + k] >= position_accessor.minValues.at(k) &&
                positions[3 * v + k] <= position_accessor.maxValues.at(k),
            "a vertex lies outside POSITION's min/max");
      Check(std::abs(normals[3 * v + k] - expected[v][3 + k]) <= 1e-5f, "a normal differs from the fit's");
    }
    for (int k = 0; k < 2; ++k) Check(uvs[2 * v + k] > 0.0f && uvs[2 * v + k] < 1.0f, "a texture coordinate is off the texture");
  }
  const tinygltf::Accessor& index_accessor = model.accessors.at(primitive.indices);
  Check(index_accessor.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT && index_accessor.count % 3 == 0 &&
            index_accessor.count == 3 * written.triangles,
        "indices are not whole triangles");
  const tinygltf::BufferView& index_view = model.bufferViews.at(index_accessor.bufferView);
  const std::vector<unsigned char>& index_buffer = model.buffers.at(index_view.buffer).data;
  Check(index_view.byteOffset + index_accessor.count * 4 <= index_buffer.size(), "indices run past their buffer");
  for (std::size_t i = 0; i < index_accessor.count; ++i) {
    std::uint32_t index;
    std::memcpy(&index, index_buffer.data() + index_view.byteOffset + 4 * i, 4);
    Check(index < vertices, "a triangle indexes a vertex that does not exist");
  }

  // The roughness texture (G of metallic_roughness.png) holds each fitted pixel's material roughness.
  Check(model.materials.size() == 1, "not one material");
  const int mr_texture = model.materials[0].pbrMetallicRoughness.metallicRoughnessTexture.index;
  const std::string mr_uri = model.images.at(model.textures.at(mr_texture).source).uri;
  auto png = [&](const std::string& name) {
    const auto found = std::find_if(written.png.begin(), written.png.end(), [&](const auto& p) { return p.first == name; });
    return found == written.png.end() ? cv::Mat() : found->second;
  };
  const cv::Mat mr = png(mr_uri);
  Check(mr.rows == rows && mr.cols == cols && mr.type() == CV_8UC3, "the roughness texture has the wrong shape");
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const int m = maps.material.at<std::uint8_t>(r, c);
      if (m >= materials) continue;
      const double roughness = std::clamp(refl::ToGltf(maps.materials[m]).roughness, 0.0, 1.0);
      Check(mr.at<cv::Vec3b>(r, c)[1] == static_cast<int>(std::lround(255.0 * roughness)),  // RGB: G is [1]
            "a pixel's roughness differs from its material's");
    }
  for (const tinygltf::Image& image : model.images)
    Check(!png(image.uri).empty(), "the asset names a texture it does not write");
  return 0;
}
