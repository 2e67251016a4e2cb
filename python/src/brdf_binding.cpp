// photorig.read_merl, write_merl and eval_brdf: measured-BRDF tables through
// the solver's own readers and writers (solvers/brdf/merl.h, measured.h), as
// `photorig brdf eval` and `convert` use them.

#include "arrays.h"
#include "bindings.h"
#include "photorig/solvers/brdf/measured.h"
#include "photorig/solvers/brdf/merl.h"

#include <cmath>
#include <limits>

namespace photorig::python {
namespace {

namespace brdf = solvers::brdf;
using Table = brdf::MerlTable;

// (3, theta_h, theta_d, phi_d) in 1/sr, NaN where a cell is not measured.
py::array_t<double> ReadMerl(const std::string& path) {
  Table table;
  brdf::MerlReadSummary read;
  {
    py::gil_scoped_release unlocked;
    read = brdf::ReadMerl(path, &table);
  }
  if (!read.IsSolutionUsable()) throw py::value_error(read.message);
  py::array_t<double> values({3, Table::kThetaHBins, Table::kThetaDBins, Table::kPhiDBins});
  double* out = values.mutable_data();
  for (int c = 0; c < 3; ++c)
    for (std::size_t cell = 0; cell < Table::kCells; ++cell) {
      const double stored = table.plane(c)[cell];
      out[c * Table::kCells + cell] = stored < 0.0 ? std::numeric_limits<double>::quiet_NaN() : stored * Table::kChannelScale[c];
    }
  return values;
}

void WriteMerl(const std::string& path, const py::array_t<double, py::array::c_style | py::array::forcecast>& values) {
  if (values.ndim() != 4 || values.shape(0) != 3 || values.shape(1) != Table::kThetaHBins ||
      values.shape(2) != Table::kThetaDBins || values.shape(3) != Table::kPhiDBins)
    throw py::value_error("a MERL table is (3, 90, 90, 180): R, G, B over theta_h, theta_d, phi_d");
  Table table;
  const double* in = values.data();
  for (std::size_t cell = 0; cell < Table::kCells; ++cell) {
    const Eigen::Vector3d value(in[cell], in[Table::kCells + cell], in[2 * Table::kCells + cell]);
    if (value.array().isNaN().any())
      table.SetCellInvalid(cell);
    else
      table.SetCell(cell, value);
  }
  py::gil_scoped_release unlocked;
  if (const solvers::core::Summary written = brdf::WriteMerl(path, table); !written.IsSolutionUsable())
    throw py::value_error(written.message);
}

// f_r in 1/sr per channel for each row of wi and wo (unit vectors, (n, 3));
// NaN rows below the horizon or where the table has no value.
py::array_t<double> EvalBrdf(const std::string& path,
                             const py::array_t<double, py::array::c_style | py::array::forcecast>& wi,
                             const py::array_t<double, py::array::c_style | py::array::forcecast>& wo) {
  if (wi.ndim() != 2 || wi.shape(1) != 3 || wo.ndim() != 2 || wo.shape(1) != 3 || wi.shape(0) != wo.shape(0))
    throw py::value_error("wi and wo must be (n, 3) arrays of unit vectors, n alike");
  brdf::MeasuredBrdf table;
  if (const solvers::core::Summary read = brdf::ReadMeasured(path, &table); !read.IsSolutionUsable())
    throw py::value_error(read.message);
  const py::ssize_t n = wi.shape(0);
  py::array_t<double> f({n, py::ssize_t{3}});
  const auto a = wi.unchecked<2>();
  const auto b = wo.unchecked<2>();
  auto out = f.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < n; ++i) {
    const std::optional<Eigen::Vector3d> value =
        table(Eigen::Vector3d(a(i, 0), a(i, 1), a(i, 2)), Eigen::Vector3d(b(i, 0), b(i, 1), b(i, 2)));
    for (int c = 0; c < 3; ++c) out(i, c) = value ? (*value)[c] : std::numeric_limits<double>::quiet_NaN();
  }
  return f;
}

}  // namespace

void BindBrdf(py::module_& m) {
  m.def("read_merl", &ReadMerl, py::arg("path"),
        "A MERL .binary as (3, 90, 90, 180) float64 R, G, B in 1/sr over (theta_h, theta_d, phi_d) bins; "
        "NaN where a cell is not measured. ValueError with the reader's message for a bad file.");
  m.def("write_merl", &WriteMerl, py::arg("path"), py::arg("values"),
        "Writes read_merl's layout as a MERL .binary (NaN: a cell not measured).");
  m.def("eval_brdf", &EvalBrdf, py::arg("path"), py::arg("wi"), py::arg("wo"),
        "A MERL .binary's or RGL .bsdf's f_r (1/sr, R, G, B) for each row of wi (towards the light) and wo "
        "(towards the camera), as `photorig brdf eval`: (n, 3), NaN rows where it has no value.");
}

}  // namespace photorig::python
