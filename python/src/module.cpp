// The extension module behind `import photorig` (python/photorig/__init__.py).

#include "bindings.h"

PYBIND11_MODULE(_photorig, m) {
  m.doc() = "photorig's runs and solvers in-process (docs/python.md)";
  photorig::python::BindRun(m);
  photorig::python::BindPs(m);
  photorig::python::BindSvbrdf(m);
  photorig::python::BindTomography(m);
  photorig::python::BindCapture(m);
  photorig::python::BindBrdf(m);
  photorig::python::BindCalibration(m);
}
