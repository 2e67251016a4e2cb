#include "photorig/sim/brdf.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <stdexcept>

namespace photorig::sim {
namespace {

using Eigen::Vector3d;

// Rodrigues' rotation of v about a unit axis.
Vector3d Rotate(const Vector3d& v, const Vector3d& axis, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return v * c + axis * axis.dot(v) * (1.0 - c) + axis.cross(v) * s;
}

// Any orthonormal frame with z = n: the models here are isotropic.
void Frame(const Vector3d& n, Vector3d* t, Vector3d* b) {
  const Vector3d helper = std::abs(n.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY();
  *t = n.cross(helper).normalized();
  *b = n.cross(*t);
}

double Schlick(double f0, double cosine) {
  const double m = std::clamp(1.0 - cosine, 0.0, 1.0);
  return f0 + (1.0 - f0) * m * m * m * m * m;
}

class Lambertian final : public Brdf {
 public:
  Model model() const override { return Model::kLambertian; }
  double Eval(const Vector3d& n, const Vector3d& wi, const Vector3d& wo, const BrdfParams& p) const override {
    if (n.dot(wi) <= 0.0 || n.dot(wo) <= 0.0) return 0.0;
    return p.rho_d / M_PI;
  }
};

class BlinnPhong final : public Brdf {
 public:
  Model model() const override { return Model::kBlinnPhong; }
  double Eval(const Vector3d& n, const Vector3d& wi, const Vector3d& wo, const BrdfParams& p) const override {
    if (n.dot(wi) <= 0.0 || n.dot(wo) <= 0.0) return 0.0;
    const double e = p.shininess;
    const double nh = std::max(0.0, n.dot((wi + wo).normalized()));
    return p.rho_d / M_PI + p.rho_s * (e + 2.0) / (2.0 * M_PI) * std::pow(nh, e);
  }
};

class Ggx final : public Brdf {
 public:
  Model model() const override { return Model::kGgx; }
  double Eval(const Vector3d& n, const Vector3d& wi, const Vector3d& wo, const BrdfParams& p) const override {
    const double ni = n.dot(wi), no = n.dot(wo);
    if (ni <= 0.0 || no <= 0.0) return 0.0;
    const Vector3d h = (wi + wo).normalized();
    const double nh = n.dot(h), a2 = double(p.shininess) * p.shininess, f0 = p.f0;
    const double t = nh * nh * (a2 - 1.0) + 1.0;
    const double d = a2 / (M_PI * t * t);
    auto g1 = [a2](double c) { return 2.0 * c / (c + std::sqrt(a2 + (1.0 - a2) * c * c)); };
    const double specular = d * g1(ni) * g1(no) * Schlick(f0, wi.dot(h)) / (4.0 * ni * no);
    // The diffuse base gets what the Fresnel interface transmits on the way
    // in and out; the symmetric form keeps reciprocity.
    const double diffuse = p.rho_d / M_PI * (1.0 - Schlick(f0, ni)) * (1.0 - Schlick(f0, no)) / (1.0 - f0);
    return specular + diffuse;
  }
};

class Mirror final : public Brdf {
 public:
  Model model() const override { return Model::kMirror; }
  double Eval(const Vector3d&, const Vector3d&, const Vector3d&, const BrdfParams&) const override { return 0.0; }
  bool IsDelta() const override { return true; }
  double DeltaReflectance(const BrdfParams& p) const override { return p.rho_s; }
};

class Tabulated final : public Brdf {
 public:
  explicit Tabulated(std::shared_ptr<const MerlTable> table) : table_(std::move(table)) {}
  Model model() const override { return Model::kTabulated; }
  double Eval(const Vector3d& n, const Vector3d& wi, const Vector3d& wo, const BrdfParams&) const override {
    if (n.dot(wi) <= 0.0 || n.dot(wo) <= 0.0) return 0.0;
    Vector3d t, b;
    Frame(n, &t, &b);
    const Vector3d li(t.dot(wi), b.dot(wi), n.dot(wi)), lo(t.dot(wo), b.dot(wo), n.dot(wo));
    double theta_h, theta_d, phi_d;
    MerlTable::HalfDiff(li, lo, &theta_h, &theta_d, &phi_d);
    return table_->Lookup(theta_h, theta_d, phi_d);
  }

 private:
  std::shared_ptr<const MerlTable> table_;
};

constexpr double kMerlScale[3] = {1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0};
constexpr std::size_t kMerlSize = std::size_t{MerlTable::kThetaH} * MerlTable::kThetaD * MerlTable::kPhiD;

}  // namespace

Vector3d MirrorDirection(const Vector3d& n, const Vector3d& wo) { return 2.0 * n.dot(wo) * n - wo; }

void MerlTable::HalfDiff(const Vector3d& wi, const Vector3d& wo, double* theta_h, double* theta_d, double* phi_d) {
  const Vector3d h = (wi + wo).normalized();
  *theta_h = std::acos(std::clamp(h.z(), -1.0, 1.0));
  const double phi_h = std::atan2(h.y(), h.x());
  const Vector3d diff = Rotate(Rotate(wi, Vector3d::UnitZ(), -phi_h), Vector3d::UnitY(), -*theta_h);
  *theta_d = std::acos(std::clamp(diff.z(), -1.0, 1.0));
  *phi_d = std::atan2(diff.y(), diff.x());
}

double MerlTable::Lookup(double theta_h, double theta_d, double phi_d) const {
  const double theta_h_deg = theta_h / (M_PI / 2.0) * 90.0;
  const int ih = theta_h <= 0.0 ? 0 : std::clamp(static_cast<int>(std::sqrt(theta_h_deg * 90.0)), 0, kThetaH - 1);
  const int id = std::clamp(static_cast<int>(theta_d / (M_PI / 2.0) * kThetaD), 0, kThetaD - 1);
  if (phi_d < 0.0) phi_d += M_PI;  // reciprocity: phi_d and phi_d + pi are the same configuration
  const int ip = std::clamp(static_cast<int>(phi_d / M_PI * kPhiD), 0, kPhiD - 1);
  return values_[(static_cast<std::size_t>(ih) * kThetaD + id) * kPhiD + ip];
}

MerlTable MerlTable::FromBlinnPhong(double rho_d, double rho_s, double exponent) {
  MerlTable table;
  table.values_.resize(kMerlSize);
  for (int ih = 0; ih < kThetaH; ++ih) {
    // Centre of the bin in the square-root mapping: theta_h_deg = (i + 0.5)^2 / 90.
    const double theta_h = (ih + 0.5) * (ih + 0.5) / 90.0 * M_PI / 180.0;
    const float f = static_cast<float>(rho_d / M_PI +
                                       rho_s * (exponent + 2.0) / (2.0 * M_PI) * std::pow(std::cos(theta_h), exponent));
    std::fill_n(table.values_.begin() + static_cast<std::ptrdiff_t>(ih) * kThetaD * kPhiD, kThetaD * kPhiD, f);
  }
  return table;
}

MerlTable MerlTable::Load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open MERL BRDF '" + path + "'");
  std::int32_t dims[3];
  in.read(reinterpret_cast<char*>(dims), sizeof dims);
  if (!in || dims[0] != kThetaH || dims[1] != kThetaD || dims[2] != kPhiD)
    throw std::runtime_error("MERL BRDF '" + path + "': header is not 90 x 90 x 180");
  std::vector<double> raw(3 * kMerlSize);
  in.read(reinterpret_cast<char*>(raw.data()), static_cast<std::streamsize>(raw.size() * sizeof(double)));
  if (!in) throw std::runtime_error("MERL BRDF '" + path + "': truncated (expected 3 x 1458000 doubles)");
  MerlTable table;
  table.values_.resize(kMerlSize);
  for (std::size_t i = 0; i < kMerlSize; ++i) {
    double sum = 0.0;
    for (int c = 0; c < 3; ++c) sum += std::max(0.0, raw[c * kMerlSize + i]) * kMerlScale[c];  // < 0 marks no data
    table.values_[i] = static_cast<float>(sum / 3.0);
  }
  return table;
}

void MerlTable::Save(const std::string& path) const {
  std::ofstream out(path, std::ios::binary);
  const std::int32_t dims[3] = {kThetaH, kThetaD, kPhiD};
  out.write(reinterpret_cast<const char*>(dims), sizeof dims);
  for (int c = 0; c < 3; ++c)
    for (float v : values_) {
      const double stored = v / kMerlScale[c];
      out.write(reinterpret_cast<const char*>(&stored), sizeof stored);
    }
  if (!out) throw std::runtime_error("cannot write MERL BRDF '" + path + "'");
}

Brdf::Model Brdf::ParseModel(const std::string& name) {
  for (Model m : {Model::kLambertian, Model::kBlinnPhong, Model::kGgx, Model::kMirror, Model::kTabulated})
    if (name == ModelName(m)) return m;
  throw std::invalid_argument("unknown BRDF '" + name +
                              "' (expected lambertian, blinn_phong, ggx, mirror or tabulated)");
}

const char* Brdf::ModelName(Model model) {
  switch (model) {
    case Model::kLambertian: return "lambertian";
    case Model::kBlinnPhong: return "blinn_phong";
    case Model::kGgx: return "ggx";
    case Model::kMirror: return "mirror";
    case Model::kTabulated: return "tabulated";
  }
  return "?";
}

std::unique_ptr<Brdf> MakeBrdf(Brdf::Model model, std::shared_ptr<const MerlTable> table) {
  switch (model) {
    case Brdf::Model::kLambertian: return std::make_unique<Lambertian>();
    case Brdf::Model::kBlinnPhong: return std::make_unique<BlinnPhong>();
    case Brdf::Model::kGgx: return std::make_unique<Ggx>();
    case Brdf::Model::kMirror: return std::make_unique<Mirror>();
    case Brdf::Model::kTabulated:
      if (!table) throw std::invalid_argument("a tabulated BRDF needs a table");
      return std::make_unique<Tabulated>(std::move(table));
  }
  return nullptr;
}

}  // namespace photorig::sim
