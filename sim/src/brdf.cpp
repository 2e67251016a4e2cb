#include "photorig/sim/brdf.h"

#include "photorig/solvers/brdf/models.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace photorig::sim {
namespace {

using Eigen::Vector3d;

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

class CookTorrance final : public Brdf {
 public:
  Model model() const override { return Model::kCookTorrance; }
  double Eval(const Vector3d& n, const Vector3d& wi, const Vector3d& wo, const BrdfParams& p) const override {
    if (n.dot(wi) <= 0.0 || n.dot(wo) <= 0.0) return 0.0;
    solvers::brdf::ModelParams model;
    model.model = solvers::brdf::Model::kCookTorrance;
    model.diffuse.setConstant(p.rho_d);
    model.specular.setConstant(p.rho_s);
    model.shape = p.shininess;
    model.fresnel_f0 = p.f0;
    Vector3d t, b;  // isotropic: any tangent frame about n
    Frame(n, &t, &b);
    return solvers::brdf::Evaluate(model, Vector3d(t.dot(wi), b.dot(wi), n.dot(wi)),
                                   Vector3d(t.dot(wo), b.dot(wo), n.dot(wo)))[0];
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
  Tabulated(std::shared_ptr<const solvers::brdf::MeasuredBrdf> table, int channel)
      : table_(std::move(table)), channel_(channel) {}
  Model model() const override { return Model::kTabulated; }
  double Eval(const Vector3d& n, const Vector3d& wi, const Vector3d& wo, const BrdfParams&) const override {
    if (n.dot(wi) <= 0.0 || n.dot(wo) <= 0.0) return 0.0;
    // The table is isotropic: any tangent frame about n will do.
    Vector3d t, b;
    Frame(n, &t, &b);
    const auto value = (*table_)(Vector3d(t.dot(wi), b.dot(wi), n.dot(wi)), Vector3d(t.dot(wo), b.dot(wo), n.dot(wo)));
    if (!value) return 0.0;  // an unmeasured cell reflects nothing rather than something invented
    return channel_ < 0 ? value->mean() : (*value)[channel_];
  }

 private:
  std::shared_ptr<const solvers::brdf::MeasuredBrdf> table_;
  int channel_;
};

}  // namespace

Vector3d MirrorDirection(const Vector3d& n, const Vector3d& wo) { return 2.0 * n.dot(wo) * n - wo; }

Brdf::Model Brdf::ParseModel(const std::string& name) {
  for (Model m : {Model::kLambertian, Model::kBlinnPhong, Model::kGgx, Model::kCookTorrance, Model::kMirror,
                  Model::kTabulated})
    if (name == ModelName(m)) return m;
  throw std::invalid_argument("unknown BRDF '" + name +
                              "' (expected lambertian, blinn_phong, ggx, cook_torrance, mirror or tabulated)");
}

const char* Brdf::ModelName(Model model) {
  switch (model) {
    case Model::kLambertian: return "lambertian";
    case Model::kBlinnPhong: return "blinn_phong";
    case Model::kGgx: return "ggx";
    case Model::kCookTorrance: return "cook_torrance";
    case Model::kMirror: return "mirror";
    case Model::kTabulated: return "tabulated";
  }
  return "?";
}

std::unique_ptr<Brdf> MakeBrdf(Brdf::Model model, std::shared_ptr<const solvers::brdf::MeasuredBrdf> table,
                               int channel) {
  switch (model) {
    case Brdf::Model::kLambertian: return std::make_unique<Lambertian>();
    case Brdf::Model::kBlinnPhong: return std::make_unique<BlinnPhong>();
    case Brdf::Model::kGgx: return std::make_unique<Ggx>();
    case Brdf::Model::kCookTorrance: return std::make_unique<CookTorrance>();
    case Brdf::Model::kMirror: return std::make_unique<Mirror>();
    case Brdf::Model::kTabulated:
      if (!table || !*table) throw std::invalid_argument("a tabulated BRDF needs a table");
      if (channel < -1 || channel > 2) throw std::invalid_argument("a table's channel is 0, 1, 2 or -1 (their mean)");
      return std::make_unique<Tabulated>(std::move(table), channel);
  }
  return nullptr;
}

}  // namespace photorig::sim
