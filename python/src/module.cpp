// The extension module behind `import photorig` (python/photorig/__init__.py).

#include "bindings.h"
#include "photorig/daemon/capture/run_store.h"

#include <exception>

PYBIND11_MODULE(_photorig, m) {
  m.doc() = "photorig's runs and solvers in-process (docs/python.md)";
  // A damaged run is the caller's input to fix, as the CLI's exit 2 says: ValueError, not RuntimeError.
  pybind11::register_exception_translator([](std::exception_ptr raised) {
    try {
      if (raised) std::rethrow_exception(raised);
    } catch (const photorig::daemon::DamagedRunError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
  photorig::python::BindRun(m);
  photorig::python::BindPs(m);
  photorig::python::BindSvbrdf(m);
  photorig::python::BindTomography(m);
  photorig::python::BindCapture(m);
  photorig::python::BindBrdf(m);
  photorig::python::BindCalibration(m);
}
