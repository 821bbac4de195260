#pragma once
// Shared by the translation units of the Python module: numpy conversions and the
// registration functions (module.cpp calls them). Thin: every computation is the engine's.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <string>
#include <vector>

#include "pneuma/core/parameters.h"
#include "pneuma/mesh/geometry/triangle_mesh.h"

namespace pneuma::python {

namespace py = pybind11;

// A float64 array of shape (n,) copied from `values` times `factor`.
py::array_t<double> column(const std::vector<double>& values, double factor = 1.0);
// (V, 3) float64 from points.
py::array_t<double> points_to_array(const std::vector<Eigen::Vector3d>& points);
// (F, 3) uint32 from triangles.
py::array_t<std::uint32_t> triangles_to_array(const std::vector<mesh::Triangle>& triangles);
// Points from an array-like of shape (V, 3); throws pneuma::ValueError naming `what` otherwise.
std::vector<Eigen::Vector3d> array_to_points(const py::handle& array, const char* what);
// Triangles from an integer array-like of shape (F, 3), each index below `vertex_count`.
std::vector<mesh::Triangle> array_to_triangles(const py::handle& array, std::size_t vertex_count);

// Raises pneuma.ValueError "<argument>: expected ..., got ..." where `value` breaks `parameter`'s
// rule (the rule the scenario reader and the CLI apply too).
void check_argument(const char* argument, const parameters::Parameter& parameter, double value);

void register_scenario(py::module_& m);    // Scenario, load_scenario, run
void register_simulation(py::module_& m);  // Simulation, simulate
void register_animation(py::module_& m);   // Animation
void register_geometry(py::module_& m);    // Mesh, load_mesh, phantom, Field

}  // namespace pneuma::python
