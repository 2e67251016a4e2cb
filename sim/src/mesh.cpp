#include "photorig/sim/mesh.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace photorig::sim {
namespace {

// Byte size of a PLY scalar type; 0 if unknown.
int TypeSize(const std::string& type) {
  if (type == "char" || type == "uchar" || type == "int8" || type == "uint8") return 1;
  if (type == "short" || type == "ushort" || type == "int16" || type == "uint16") return 2;
  if (type == "int" || type == "uint" || type == "int32" || type == "uint32" || type == "float" || type == "float32")
    return 4;
  if (type == "double" || type == "float64") return 8;
  return 0;
}

double Decode(const std::string& type, const char* bytes) {
  auto get = [bytes](auto value) {
    std::memcpy(&value, bytes, sizeof value);
    return static_cast<double>(value);
  };
  if (type == "char" || type == "int8") return get(std::int8_t{});
  if (type == "uchar" || type == "uint8") return get(std::uint8_t{});
  if (type == "short" || type == "int16") return get(std::int16_t{});
  if (type == "ushort" || type == "uint16") return get(std::uint16_t{});
  if (type == "int" || type == "int32") return get(std::int32_t{});
  if (type == "uint" || type == "uint32") return get(std::uint32_t{});
  if (type == "float" || type == "float32") return get(float{});
  return get(double{});
}

struct Property {
  std::string name, type;
  std::string count_type;  // non-empty for list properties
};

struct Element {
  std::string name;
  std::size_t count = 0;
  std::vector<Property> properties;
};

// Reads one element instance's values in order (a list contributes its
// count followed by its items).
class ValueReader {
 public:
  ValueReader(std::istream& in, bool binary, std::string path) : in_(in), binary_(binary), path_(std::move(path)) {}

  double Next(const std::string& type) {
    if (!binary_) {
      double v;
      if (!(in_ >> v)) Fail("truncated or malformed ASCII data");
      return v;
    }
    char bytes[8];
    if (!in_.read(bytes, TypeSize(type))) Fail("truncated binary data");
    return Decode(type, bytes);
  }
  [[noreturn]] void Fail(const std::string& what) const { throw std::runtime_error("PLY '" + path_ + "': " + what); }

 private:
  std::istream& in_;
  bool binary_;
  std::string path_;
};

}  // namespace

TriangleMesh LoadPly(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open PLY '" + path + "'");
  auto fail = [&path](const std::string& what) { throw std::runtime_error("PLY '" + path + "': " + what); };
  std::string line;
  if (!std::getline(in, line) || line.rfind("ply", 0) != 0) fail("missing 'ply' magic");
  bool binary = false;
  std::vector<Element> elements;
  for (int line_number = 2; std::getline(in, line); ++line_number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    const std::string where = "header line " + std::to_string(line_number) + ": ";
    if (keyword == "end_header") break;
    if (keyword == "comment" || keyword == "obj_info" || keyword.empty()) continue;
    if (keyword == "format") {
      std::string format;
      words >> format;
      if (format == "binary_little_endian") binary = true;
      else if (format != "ascii") fail(where + "unsupported format '" + format + "' (ascii or binary_little_endian)");
    } else if (keyword == "element") {
      Element e;
      if (!(words >> e.name >> e.count)) fail(where + "malformed element");
      elements.push_back(e);
    } else if (keyword == "property") {
      if (elements.empty()) fail(where + "property before any element");
      Property p;
      words >> p.type;
      if (p.type == "list") words >> p.count_type >> p.type;
      words >> p.name;
      if (TypeSize(p.type) == 0 || (!p.count_type.empty() && TypeSize(p.count_type) == 0))
        fail(where + "unknown property type");
      elements.back().properties.push_back(p);
    } else {
      fail(where + "unexpected '" + keyword + "'");
    }
  }
  TriangleMesh mesh;
  ValueReader reader(in, binary, path);
  for (const Element& e : elements) {
    const bool is_vertex = e.name == "vertex", is_face = e.name == "face";
    int axis_of[3] = {-1, -1, -1};
    int index_property = -1;
    for (std::size_t i = 0; i < e.properties.size(); ++i) {
      const Property& p = e.properties[i];
      if (is_vertex && p.count_type.empty() && p.name.size() == 1 && p.name[0] >= 'x' && p.name[0] <= 'z')
        axis_of[p.name[0] - 'x'] = static_cast<int>(i);
      if (is_face && !p.count_type.empty() && (p.name == "vertex_indices" || p.name == "vertex_index"))
        index_property = static_cast<int>(i);
    }
    if (is_vertex && (axis_of[0] < 0 || axis_of[1] < 0 || axis_of[2] < 0)) fail("vertices lack x, y or z");
    if (is_face && index_property < 0) fail("faces lack a vertex_indices list");
    for (std::size_t n = 0; n < e.count; ++n) {
      Eigen::Vector3d v = Eigen::Vector3d::Zero();
      std::vector<int> polygon;
      for (std::size_t i = 0; i < e.properties.size(); ++i) {
        const Property& p = e.properties[i];
        if (p.count_type.empty()) {
          const double value = reader.Next(p.type);
          for (int a = 0; a < 3; ++a)
            if (axis_of[a] == static_cast<int>(i)) v[a] = value;
          continue;
        }
        const double count = reader.Next(p.count_type);
        if (!(count >= 0 && count < 1e6)) fail("implausible list length in element '" + e.name + "'");
        for (int k = 0; k < static_cast<int>(count); ++k) {
          const double value = reader.Next(p.type);
          if (static_cast<int>(i) == index_property) polygon.push_back(static_cast<int>(value));
        }
      }
      if (is_vertex) mesh.vertices.push_back(v);
      if (is_face) {
        if (polygon.size() < 3) fail("face " + std::to_string(n) + " has fewer than 3 vertices");
        for (std::size_t k = 1; k + 1 < polygon.size(); ++k) mesh.faces.emplace_back(polygon[0], polygon[k], polygon[k + 1]);
      }
    }
  }
  const int vertex_count = static_cast<int>(mesh.vertices.size());
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (int k = 0; k < 3; ++k)
      if (mesh.faces[f][k] < 0 || mesh.faces[f][k] >= vertex_count)
        fail("face " + std::to_string(f) + " refers to vertex " + std::to_string(mesh.faces[f][k]) + " of " +
             std::to_string(vertex_count));
  if (mesh.faces.empty()) fail("no faces");
  return mesh;
}

void SavePly(const std::string& path, const TriangleMesh& mesh, bool binary) {
  std::ofstream out(path, std::ios::binary);
  out << "ply\nformat " << (binary ? "binary_little_endian" : "ascii") << " 1.0\n"
      << "element vertex " << mesh.vertices.size() << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "element face " << mesh.faces.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
  out.precision(9);
  for (const auto& v : mesh.vertices) {
    if (!binary) {
      out << v.x() << ' ' << v.y() << ' ' << v.z() << '\n';
      continue;
    }
    const float xyz[3] = {float(v.x()), float(v.y()), float(v.z())};
    out.write(reinterpret_cast<const char*>(xyz), sizeof xyz);
  }
  for (const auto& f : mesh.faces) {
    if (!binary) {
      out << "3 " << f[0] << ' ' << f[1] << ' ' << f[2] << '\n';
      continue;
    }
    const std::uint8_t three = 3;
    const std::int32_t idx[3] = {f[0], f[1], f[2]};
    out.write(reinterpret_cast<const char*>(&three), 1);
    out.write(reinterpret_cast<const char*>(idx), sizeof idx);
  }
  if (!out) throw std::runtime_error("cannot write PLY '" + path + "'");
}

void RasterizeOrthographic(const TriangleMesh& mesh, const CameraModel& camera, cv::Mat* height, cv::Mat* normals) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  *height = cv::Mat(camera.height, camera.width, CV_32F, cv::Scalar(nan));
  *normals = cv::Mat(camera.height, camera.width, CV_32FC3, cv::Scalar::all(nan));
  const double pitch = camera.pixel_pitch_mm;
  // Continuous pixel coordinates with pixel centres at integers.
  auto col_of = [&](double x) { return x / pitch + 0.5 * camera.width - 0.5; };
  auto row_of = [&](double y) { return 0.5 * camera.height - y / pitch - 0.5; };
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3d &a = mesh.vertices[f[0]], &b = mesh.vertices[f[1]], &c = mesh.vertices[f[2]];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() == 0.0) continue;
    n.normalize();
    if (n.z() < 0.0) n = -n;  // seen from the camera, whatever the winding
    const double ac = col_of(a.x()), ar = row_of(a.y()), bc = col_of(b.x()), br = row_of(b.y()), cc = col_of(c.x()),
                 cr = row_of(c.y());
    const double area = (bc - ac) * (cr - ar) - (br - ar) * (cc - ac);
    if (std::abs(area) < 1e-12) continue;  // edge-on: covers no pixel centre
    const int c0 = std::max(0, static_cast<int>(std::ceil(std::min({ac, bc, cc})))),
              c1 = std::min(camera.width - 1, static_cast<int>(std::floor(std::max({ac, bc, cc})))),
              r0 = std::max(0, static_cast<int>(std::ceil(std::min({ar, br, cr})))),
              r1 = std::min(camera.height - 1, static_cast<int>(std::floor(std::max({ar, br, cr}))));
    for (int r = r0; r <= r1; ++r)
      for (int col = c0; col <= c1; ++col) {
        // Barycentric weights; a small tolerance closes the cracks between triangles.
        const double wa = ((bc - col) * (cr - r) - (br - r) * (cc - col)) / area;
        const double wb = ((cc - col) * (ar - r) - (cr - r) * (ac - col)) / area;
        const double wc = 1.0 - wa - wb;
        if (wa < -1e-9 || wb < -1e-9 || wc < -1e-9) continue;
        const float z = static_cast<float>(wa * a.z() + wb * b.z() + wc * c.z());
        float& current = height->at<float>(r, col);
        if (std::isfinite(current) && current >= z) continue;
        current = z;
        normals->at<cv::Vec3f>(r, col) = cv::Vec3f(float(n.x()), float(n.y()), float(n.z()));
      }
  }
}

}  // namespace photorig::sim
