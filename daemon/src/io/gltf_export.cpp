#include "photorig/daemon/io/gltf_export.h"

#include "gltf_model.h"
#include "photorig/daemon/io/image_io.h"
#include "photorig/solvers/reflectance/gltf_material.h"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace photorig::daemon {
namespace {

namespace fs = std::filesystem;
namespace refl = solvers::reflectance;

std::uint8_t ToSrgb8(double linear) {
  const double v = std::clamp(linear, 0.0, 1.0);
  const double s = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
  return static_cast<std::uint8_t>(std::lround(255.0 * s));
}

std::uint8_t ToUnit8(double v) { return static_cast<std::uint8_t>(std::lround(255.0 * std::clamp(v, 0.0, 1.0))); }

// Textures are held in glTF's channel order (R, G, B); files are written from OpenCV's (B, G, R).
void WriteRgbImage(const fs::path& path, const cv::Mat& rgb) {
  cv::Mat bgr = rgb;
  if (rgb.channels() == 3) cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  WriteImage(path.string(), bgr);
}

int AddTexture(tinygltf::Model* model, const std::string& uri) {
  tinygltf::Image image;
  image.uri = uri;
  image.mimeType = "image/png";
  model->images.push_back(image);
  tinygltf::Texture texture;
  texture.source = static_cast<int>(model->images.size()) - 1;
  texture.sampler = 0;
  model->textures.push_back(texture);
  return static_cast<int>(model->textures.size()) - 1;
}

template <typename T>
int AddAccessor(tinygltf::Model* model, std::vector<unsigned char>* bin, const std::vector<T>& data, int component,
                int type, int target, std::size_t count) {
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = bin->size();
  view.byteLength = data.size() * sizeof(T);
  view.target = target;
  const auto* bytes = reinterpret_cast<const unsigned char*>(data.data());
  bin->insert(bin->end(), bytes, bytes + view.byteLength);
  while (bin->size() % 4) bin->push_back(0);
  model->bufferViews.push_back(view);
  tinygltf::Accessor accessor;
  accessor.bufferView = static_cast<int>(model->bufferViews.size()) - 1;
  accessor.componentType = component;
  accessor.type = type;
  accessor.count = count;
  model->accessors.push_back(accessor);
  return static_cast<int>(model->accessors.size()) - 1;
}

}  // namespace

void GltfParameterMaps(const refl::ReflectanceMaps& maps, cv::Mat* roughness, cv::Mat* f0) {
  *roughness = cv::Mat(maps.material.size(), CV_32F, cv::Scalar(0));
  *f0 = cv::Mat(maps.material.size(), CV_32FC3, cv::Scalar::all(0));
  for (int r = 0; r < maps.material.rows; ++r)
    for (int c = 0; c < maps.material.cols; ++c) {
      const int m = maps.material.at<std::uint8_t>(r, c);
      if (m >= static_cast<int>(maps.materials.size())) continue;
      const refl::GltfMaterial g = refl::ToGltf(maps.materials[m]);
      roughness->at<float>(r, c) = static_cast<float>(g.roughness);
      const Eigen::Vector3d spec = maps.materials[m].model == solvers::brdf::Model::kLambertian
                                       ? Eigen::Vector3d::Zero()
                                       : Eigen::Vector3d(0.04 * g.specular_colour);
      const bool mono = maps.albedo.channels() == 1;
      f0->at<cv::Vec3f>(r, c) = cv::Vec3f(static_cast<float>(spec[0]), static_cast<float>(mono ? spec[0] : spec[1]),
                                          static_cast<float>(mono ? spec[0] : spec[2]));
    }
}

namespace internal {

GltfModel BuildGltfModel(const refl::ReflectanceMaps& maps, const cv::Mat& depth,
                         const solvers::camera::PixelRays& rays) {
  GltfModel asset;
  const int rows = maps.albedo.rows, cols = maps.albedo.cols, C = maps.albedo.channels();
  cv::Mat roughness, f0;
  GltfParameterMaps(maps, &roughness, &f0);

  // Textures (8-bit PNG for the glTF, EXR for exact values).
  cv::Mat base(rows, cols, CV_8UC3, cv::Scalar::all(0)), mr(rows, cols, CV_8UC3, cv::Scalar::all(0));
  cv::Mat spec(rows, cols, CV_8UC3, cv::Scalar::all(0)), normal(rows, cols, CV_8UC3, cv::Scalar(128, 128, 255));
  cv::Mat albedo3(rows, cols, CV_32FC3, cv::Scalar::all(0));
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      if (maps.material.at<std::uint8_t>(r, c) >= maps.materials.size()) continue;
      const float* a = maps.albedo.ptr<float>(r) + c * C;
      const refl::GltfMaterial g = refl::ToGltf(maps.materials[maps.material.at<std::uint8_t>(r, c)]);
      for (int ch = 0; ch < 3; ++ch) {
        const float v = a[C == 1 ? 0 : ch];
        albedo3.at<cv::Vec3f>(r, c)[ch] = v;
        base.at<cv::Vec3b>(r, c)[ch] = ToSrgb8(refl::GltfBaseColour(v, g, C == 1 ? 0 : ch));
        spec.at<cv::Vec3b>(r, c)[ch] = ToUnit8(f0.at<cv::Vec3f>(r, c)[ch] / 0.04 / kGltfSpecularColourScale);
      }
      mr.at<cv::Vec3b>(r, c) = cv::Vec3b(0, ToUnit8(roughness.at<float>(r, c)), 0);
      const cv::Vec3f n = maps.normals.at<cv::Vec3f>(r, c);
      for (int ch = 0; ch < 3; ++ch) normal.at<cv::Vec3b>(r, c)[ch] = ToUnit8(0.5 * (n[ch] + 1.0));
    }
  cv::Mat normals_rgb = maps.normals.clone();
  cv::patchNaNs(normals_rgb, 0.0);
  asset.png = {{"base_colour.png", base}, {"metallic_roughness.png", mr}, {"specular_colour.png", spec},
               {"normal.png", normal}};
  asset.exr = {{"albedo.exr", albedo3}, {"roughness.exr", roughness}, {"specular.exr", f0},
               {"normals.exr", normals_rgb}};

  // Mesh: a vertex per fitted pixel with finite depth.
  std::vector<float> positions, normals, uvs;
  std::vector<std::uint32_t> indices;
  cv::Mat index(rows, cols, CV_32S, cv::Scalar(-1));
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e30f), hi = Eigen::Vector3f::Constant(-1e30f);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const float z = depth.at<float>(r, c);
      const cv::Vec3f n = maps.normals.at<cv::Vec3f>(r, c);
      if (maps.material.at<std::uint8_t>(r, c) >= maps.materials.size() || !std::isfinite(z) || !std::isfinite(n[0]))
        continue;
      index.at<int>(r, c) = static_cast<int>(positions.size() / 3);
      const Eigen::Vector3f p = rays.Point(r, c, z).cast<float>();
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
      positions.insert(positions.end(), {p.x(), p.y(), p.z()});
      const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      normals.insert(normals.end(), {n[0] / len, n[1] / len, n[2] / len});
      uvs.insert(uvs.end(), {static_cast<float>((c + 0.5) / cols), static_cast<float>((r + 0.5) / rows)});
    }
  for (int r = 0; r + 1 < rows; ++r)
    for (int c = 0; c + 1 < cols; ++c) {
      const int a = index.at<int>(r, c), b = index.at<int>(r + 1, c), d = index.at<int>(r, c + 1),
                e = index.at<int>(r + 1, c + 1);
      if (a < 0 || b < 0 || d < 0 || e < 0) continue;
      // Counter-clockwise seen from +z (y up, rows down).
      indices.insert(indices.end(), {static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b), static_cast<std::uint32_t>(d)});
      indices.insert(indices.end(), {static_cast<std::uint32_t>(d), static_cast<std::uint32_t>(b), static_cast<std::uint32_t>(e)});
    }
  if (positions.empty()) throw std::runtime_error("no fitted pixel has a depth");

  tinygltf::Model& model = asset.model;
  model.asset.version = "2.0";
  model.asset.generator = "photorig solve svbrdf";
  model.extensionsUsed = {"KHR_materials_specular"};
  tinygltf::Sampler sampler;
  sampler.magFilter = TINYGLTF_TEXTURE_FILTER_NEAREST;
  sampler.minFilter = TINYGLTF_TEXTURE_FILTER_NEAREST;
  model.samplers.push_back(sampler);
  std::vector<unsigned char> bin;
  const std::size_t vertex_count = positions.size() / 3;
  const int pos = AddAccessor(&model, &bin, positions, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3,
                              TINYGLTF_TARGET_ARRAY_BUFFER, vertex_count);
  model.accessors[pos].minValues = {lo.x(), lo.y(), lo.z()};
  model.accessors[pos].maxValues = {hi.x(), hi.y(), hi.z()};
  const int nrm = AddAccessor(&model, &bin, normals, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3,
                              TINYGLTF_TARGET_ARRAY_BUFFER, vertex_count);
  const int uv = AddAccessor(&model, &bin, uvs, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2,
                             TINYGLTF_TARGET_ARRAY_BUFFER, vertex_count);
  const int idx = AddAccessor(&model, &bin, indices, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR,
                              TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER, indices.size());
  tinygltf::Buffer buffer;
  buffer.data = bin;
  buffer.uri = "asset.bin";
  model.buffers.push_back(buffer);

  tinygltf::Material material;
  material.name = "svbrdf";
  material.pbrMetallicRoughness.baseColorTexture.index = AddTexture(&model, "base_colour.png");
  material.pbrMetallicRoughness.metallicRoughnessTexture.index = AddTexture(&model, "metallic_roughness.png");
  material.pbrMetallicRoughness.metallicFactor = 1.0;   // times the texture's B = 0
  material.pbrMetallicRoughness.roughnessFactor = 1.0;  // times the texture's G
  tinygltf::Value::Object specular;
  specular["specularFactor"] = tinygltf::Value(1.0);
  tinygltf::Value::Object spec_texture;
  spec_texture["index"] = tinygltf::Value(AddTexture(&model, "specular_colour.png"));
  specular["specularColorTexture"] = tinygltf::Value(spec_texture);
  specular["specularColorFactor"] = tinygltf::Value(tinygltf::Value::Array{
      tinygltf::Value(kGltfSpecularColourScale), tinygltf::Value(kGltfSpecularColourScale),
      tinygltf::Value(kGltfSpecularColourScale)});
  material.extensions["KHR_materials_specular"] = tinygltf::Value(specular);
  model.materials.push_back(material);

  tinygltf::Primitive primitive;
  primitive.attributes["POSITION"] = pos;
  primitive.attributes["NORMAL"] = nrm;
  primitive.attributes["TEXCOORD_0"] = uv;
  primitive.indices = idx;
  primitive.material = 0;
  primitive.mode = TINYGLTF_MODE_TRIANGLES;
  tinygltf::Mesh mesh;
  mesh.name = "object";
  mesh.primitives.push_back(primitive);
  model.meshes.push_back(mesh);
  tinygltf::Node node;
  node.mesh = 0;
  model.nodes.push_back(node);
  tinygltf::Scene scene;
  scene.nodes.push_back(0);
  model.scenes.push_back(scene);
  model.defaultScene = 0;

  asset.vertices = vertex_count;
  asset.triangles = indices.size() / 3;
  return asset;
}

}  // namespace internal

GltfExport WriteGltfAsset(const std::string& directory, const refl::ReflectanceMaps& maps, const cv::Mat& depth,
                          const solvers::camera::PixelRays& rays) {
  internal::GltfModel asset;
  try {
    asset = internal::BuildGltfModel(maps, depth, rays);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("glTF export to " + directory + ": " + e.what());
  }
  const fs::path dir(directory);
  fs::create_directories(dir);
  for (const auto& [name, image] : asset.png) WriteRgbImage(dir / name, image);
  for (const auto& [name, image] : asset.exr) WriteRgbImage(dir / name, image);
  GltfExport out;
  out.gltf_path = (dir / "asset.gltf").string();
  tinygltf::TinyGLTF writer;
  // Buffers to asset.bin beside it; images stay the PNGs written above.
  if (!writer.WriteGltfSceneToFile(&asset.model, out.gltf_path, false, false, true, false))
    throw std::runtime_error("cannot write " + out.gltf_path);
  out.vertices = asset.vertices;
  out.triangles = asset.triangles;
  return out;
}

}  // namespace photorig::daemon
