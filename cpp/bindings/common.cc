// The non-template half of the options-class pattern (common.h).
#include "common.h"

#include <algorithm>
#include <stdexcept>

namespace qogi {

std::string ShapeOf(const py::array& a) {
  std::string s = "(";
  for (int k = 0; k < a.ndim(); ++k) s += (k ? ", " : "") + std::to_string(a.shape(k));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

const double* OptionalValues(const py::object& value, std::size_t size, const char* name,
                             const std::string& what, DoubleArray* keep) {
  if (value.is_none()) return nullptr;
  *keep = value.cast<DoubleArray>();
  if (static_cast<std::size_t>(keep->size()) != size)
    throw std::invalid_argument(std::string(name) + " needs " + what + "; got shape " +
                                ShapeOf(*keep));
  return keep->data();
}

namespace bind_detail {

void RejectUnknown(const char* type_name, const py::kwargs& unknown,
                   const std::vector<std::string>& names) {
  if (unknown.empty()) return;
  std::string list;
  for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
  for (auto item : unknown) {
    const std::string key = py::str(item.first);
    if (std::find(names.begin(), names.end(), key) == names.end())
      throw py::type_error(std::string(type_name) + " has no field '" + key + "'; fields: " + list);
  }
}

void DefOptionsMethods(py::object cls, std::vector<std::string> names) {
  auto to_dict = [names](const py::object& self) {
    py::dict d;
    for (const auto& n : names) d[n.c_str()] = self.attr(n.c_str());
    return d;
  };
  cls.attr("to_dict") = py::cpp_function(to_dict, py::name("to_dict"), py::is_method(cls),
                                         "The fields as a dict (name -> value).");
  cls.attr("__repr__") = py::cpp_function(
      [names](const py::object& self) {
        std::string s = py::str(py::type::of(self).attr("__name__"));
        s += "(";
        for (std::size_t i = 0; i < names.size(); ++i) {
          if (i) s += ", ";
          s += names[i] + "=" + std::string(py::repr(self.attr(names[i].c_str())));
        }
        return s + ")";
      },
      py::name("__repr__"), py::is_method(cls));
  cls.attr("__eq__") = py::cpp_function(
      [to_dict](const py::object& a, const py::object& b) {
        if (!py::isinstance(b, py::type::of(a))) return false;
        return to_dict(a).equal(to_dict(b));
      },
      py::name("__eq__"), py::is_method(cls));
  cls.attr("__hash__") = py::none();  // mutable fields: not hashable (as a Python dataclass)
  py::tuple fields(names.size());
  for (std::size_t i = 0; i < names.size(); ++i) fields[i] = py::str(names[i]);
  cls.attr("fields") = fields;
}

void SetFields(py::object obj, const py::dict& state) {
  for (auto item : state) obj.attr(py::str(item.first)) = item.second;
}

}  // namespace bind_detail
}  // namespace qogi
