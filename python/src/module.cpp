// The extension pneuma._pneuma: exceptions, numpy conversions, and the module itself.
#include <fmt/format.h>

#include "bindings.h"
#include "pneuma/core/error.h"

namespace pneuma::python {
namespace {

// The Python classes of pneuma's errors, created once at import (module lifetime).
struct ErrorTypes {
  PyObject* error = nullptr;
  PyObject* input = nullptr;
  PyObject* io = nullptr;
  PyObject* usage = nullptr;
  PyObject* unsupported = nullptr;
  PyObject* value = nullptr;
};
ErrorTypes error_types;

PyObject* new_error_type(py::module_& m, const char* name, const char* doc, PyObject* bases) {
  const std::string qualified = std::string("pneuma.") + name;
  PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases, nullptr);
  if (!type) throw py::error_already_set();
  m.add_object(name, py::handle(type));  // the module keeps a reference
  return type;
}

PyObject* type_of(const Error& e) {
  if (dynamic_cast<const ValueError*>(&e)) return error_types.value;
  if (dynamic_cast<const InputError*>(&e)) return error_types.input;
  if (dynamic_cast<const IoError*>(&e)) return error_types.io;
  if (dynamic_cast<const UsageError*>(&e)) return error_types.usage;
  if (dynamic_cast<const UnsupportedError*>(&e)) return error_types.unsupported;
  return error_types.error;
}

// Raises the Python class of `e` with the same one-line message and its exit code.
void raise_error(const Error& e) {
  PyObject* type = type_of(e);
  py::object exc = py::reinterpret_borrow<py::object>(type)(e.what());
  exc.attr("exit_code") = static_cast<int>(e.code());
  PyErr_SetObject(type, exc.ptr());
}

void register_errors(py::module_& m) {
  error_types.error = new_error_type(
      m, "Error",
      "Any failure reported by pneuma. str(e) is the one line the CLI prints (file:line:col: key.path: what "
      "was expected); e.exit_code is the exit code the CLI would return (1-5, README.md).",
      PyExc_Exception);
  error_types.input = new_error_type(m, "InputError", "A bad input file or value (exit code 3).", error_types.error);
  error_types.io =
      new_error_type(m, "IoError", "A file that cannot be read or written (exit code 4).", error_types.error);
  error_types.usage = new_error_type(m, "UsageError", "A bad option (exit code 2).", error_types.error);
  error_types.unsupported = new_error_type(
      m, "UnsupportedError",
      "Valid input that pneuma cannot handle, e.g. a volume the field cannot reach (exit code 5).", error_types.error);
  py::tuple value_bases = py::make_tuple(py::handle(error_types.error), py::handle(PyExc_ValueError));
  error_types.value = new_error_type(
      m, "ValueError", "A value a function cannot take (exit code 3); also a builtin ValueError.", value_bases.ptr());
  // pybind11 takes a plain function pointer with exactly this signature (exception_ptr by value).
  py::register_exception_translator([](std::exception_ptr p) {  // NOLINT(performance-unnecessary-value-param)
    if (!p) return;
    try {
      std::rethrow_exception(p);
    } catch (const Error& e) {
      raise_error(e);
    }
  });
}

}  // namespace

void check_argument(const char* argument, const parameters::Parameter& parameter, double value) {
  if (const auto why = parameter.check(value)) throw ValueError(std::string(argument) + ": " + *why);
}

py::array_t<double> column(const std::vector<double>& values, double factor) {
  py::array_t<double> out(static_cast<py::ssize_t>(values.size()));
  auto view = out.mutable_unchecked<1>();
  for (std::size_t i = 0; i < values.size(); ++i) view(static_cast<py::ssize_t>(i)) = values[i] * factor;
  return out;
}

py::array_t<double> points_to_array(const std::vector<Eigen::Vector3d>& points) {
  py::array_t<double> out({static_cast<py::ssize_t>(points.size()), py::ssize_t{3}});
  auto view = out.mutable_unchecked<2>();
  for (std::size_t i = 0; i < points.size(); ++i) {
    for (py::ssize_t k = 0; k < 3; ++k) view(static_cast<py::ssize_t>(i), k) = points[i][k];
  }
  return out;
}

py::array_t<std::uint32_t> triangles_to_array(const std::vector<mesh::Triangle>& triangles) {
  py::array_t<std::uint32_t> out({static_cast<py::ssize_t>(triangles.size()), py::ssize_t{3}});
  auto view = out.mutable_unchecked<2>();
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    for (py::ssize_t k = 0; k < 3; ++k)
      view(static_cast<py::ssize_t>(i), k) = triangles[i][static_cast<std::size_t>(k)];
  }
  return out;
}

namespace {

std::string shape_text(const py::array& a) {
  std::string text = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) text += (d ? ", " : "") + std::to_string(a.shape(d));
  return text + (a.ndim() == 1 ? ",)" : ")");
}

}  // namespace

std::vector<Eigen::Vector3d> array_to_points(const py::handle& array, const char* what) {
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
  if (!a) throw ValueError(fmt::format("{}: expected an array of floats of shape (V, 3)", what));
  if (a.ndim() != 2 || a.shape(1) != 3) {
    throw ValueError(fmt::format("{}: expected an array of shape (V, 3), got shape {}", what, shape_text(a)));
  }
  const auto view = a.unchecked<2>();
  std::vector<Eigen::Vector3d> points(static_cast<std::size_t>(a.shape(0)));
  for (py::ssize_t i = 0; i < a.shape(0); ++i)
    points[static_cast<std::size_t>(i)] = {view(i, 0), view(i, 1), view(i, 2)};
  return points;
}

std::vector<mesh::Triangle> array_to_triangles(const py::handle& array, std::size_t vertex_count) {
  const py::array any = py::array::ensure(array);
  if (!any || !(any.dtype().kind() == 'i' || any.dtype().kind() == 'u')) {
    throw ValueError("triangles: expected an array of integer vertex indices of shape (F, 3)");
  }
  const auto a = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(any);
  if (a.ndim() != 2 || a.shape(1) != 3) {
    throw ValueError("triangles: expected an array of shape (F, 3), got shape " + shape_text(a));
  }
  const auto view = a.unchecked<2>();
  std::vector<mesh::Triangle> triangles(static_cast<std::size_t>(a.shape(0)));
  for (py::ssize_t i = 0; i < a.shape(0); ++i) {
    for (py::ssize_t k = 0; k < 3; ++k) {
      const std::int64_t index = view(i, k);
      if (index < 0 || static_cast<std::uint64_t>(index) >= vertex_count) {
        throw ValueError(fmt::format("triangles: row {} has vertex index {}, expected 0 to {}", i, index,
                                     static_cast<std::int64_t>(vertex_count) - 1));
      }
      triangles[static_cast<std::size_t>(i)][static_cast<std::size_t>(k)] = static_cast<std::uint32_t>(index);
    }
  }
  return triangles;
}

}  // namespace pneuma::python

PYBIND11_MODULE(_pneuma, m) {
  namespace pp = pneuma::python;
  m.doc() = "pneuma: breathing 3D lungs. Lumped physiology (CVODE) gives the lung volume V(t); a precomputed "
            "elastostatic field u moves the rest mesh: frame = rest + s(V) * u. See docs/python.md.";
  m.attr("__version__") = PNEUMA_VERSION;
  pp::register_errors(m);
  pp::register_geometry(m);
  pp::register_scenario(m);
  pp::register_simulation(m);
  pp::register_animation(m);
}
