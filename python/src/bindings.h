#pragma once
// One function per part of the module; module.cpp calls them in order.

#include <pybind11/pybind11.h>

namespace photorig::python {

void BindRun(pybind11::module_& m);  // open_run, Run
void BindPs(pybind11::module_& m);   // solve_ps
void BindSvbrdf(pybind11::module_& m);  // solve_svbrdf
void BindTomography(pybind11::module_& m);  // solve_tomography
void BindCapture(pybind11::module_& m);     // run_recipe
void BindBrdf(pybind11::module_& m);        // read_merl, write_merl, eval_brdf, fit_brdf, solve_brdf
void BindCalibration(pybind11::module_& m);  // calibrate_lights, calibrate_leds, calibrate_color

}  // namespace photorig::python
