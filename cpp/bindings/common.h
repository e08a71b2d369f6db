// Shared glue for the bindings: the one pattern every module binds its
// options structs with, array conversion, array checks, GIL-aware run control.
//
// How to bind an options struct (default member values and, when it
// validates itself, `void Check() const` throwing std::invalid_argument):
//
//   BindOptions<FooOptions>(m, "FooOptions", "Options of Foo (engine/foo/foo.h).",
//                           Args::kKeywordOnly,
//       Field("alpha", &FooOptions::alpha, "smoothness weight, > 0 (default 0.1)"),
//       Field("levels", &FooOptions::levels, "pyramid levels, 1-12 (default 5)"));
//
// Python then sees FooOptions(*, alpha=0.1, levels=5): a constructor whose
// defaults are the struct's (in the signature and the stubs), an unknown name
// raises TypeError ("FooOptions has no field 'x'; fields: ..."), the result is
// checked with Check() (a failure is ValueError); read/write attributes with
// the docs; check() (if the struct has Check()), to_dict(), repr naming the
// class, ==, pickle, and the class attribute `fields` (the names in order).
// Args::kPositional also accepts the fields positionally, in table order.
// Required(Field(...)) has no default; Property<V>(name, get, set, doc) binds
// a value seen by Python as a V through a getter and a setter (e.g. an enum
// as its name). BindOptions returns the py::class_ for further methods.
// ToDict(obj, Field(...)...) turns a result struct into a dict the same way.
// The fields are writable, so a getter of options an engine object holds
// returns a copy: def_property_readonly(..., py::return_value_policy::copy).
//
// How to bind a function taking arrays (glue only; the work is the engine's):
//
//   m.def("foo",
//         [](const DoubleArray& x, py::object progress) {
//           CheckNdim(x, 1, "x_m");                        // shapes checked on entry
//           std::vector<double> out(x.size());
//           RunControl control = MakeRunControl(progress);  // Ctrl-C, progress
//           {
//             py::gil_scoped_release release;               // no Python in here
//             Foo(x.data(), x.size(), out.data(), &control);
//           }
//           return ToArray(out);                            // a new 1-D array
//         },
//         py::arg("x_m"), py::arg("progress") = py::none(), "What, with units.");
//
// DoubleArray converts any input to contiguous float64 (a copy only when
// needed); FloatArray takes float32 C-contiguous frames without a copy (and
// may be written in place). ToVector / FlatVector copy an array into a
// std::vector, ToArray copies a std::vector into a new array, MapValues
// applies a function to every value of an array, OutputArrays
// allocates the arrays an engine call fills and returns them as a dict.
#pragma once

#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "engine/util/check.h"
#include "engine/util/parallel.h"

namespace qogi {
namespace py = pybind11;

// A contiguous float64 array (input is converted when needed).
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
// A contiguous float32 array that must already be float32 and C-contiguous
// (big frame stacks cross without copies).
using FloatArray = py::array_t<float, py::array::c_style>;
// A contiguous int array (input is converted when needed).
using IntArray = py::array_t<int, py::array::c_style | py::array::forcecast>;

// Throws std::invalid_argument unless `a` has `ndim` dimensions.
void CheckNdim(const py::array& a, int ndim, const char* name);

// An array's shape as text, "(3, 4)" or "(5,)", for error messages.
std::string ShapeOf(const py::array& a);

// A RunControl whose `cancelled` hook honours Ctrl-C (PyErr_CheckSignals) and,
// when given, a Python callable progress(fraction) -> bool|None that returns
// False to cancel. The hooks take the GIL themselves, so the computation may
// run with the GIL released.
RunControl MakeRunControl(py::object progress = py::none());

// --- array conversion --------------------------------------------------------

// A copy of `v` as a new 1-D array.
template <typename T>
py::array_t<T> ToArray(const std::vector<T>& v) {
  return py::array_t<T>(static_cast<py::ssize_t>(v.size()), v.data());
}

// A copy of `v` as a new C-ordered array of `shape` (whose product is v.size()),
// converted to Out (e.g. ToArray<float>(doubles, shape)).
template <typename Out = void, typename T>
auto ToArray(const std::vector<T>& v, const std::vector<py::ssize_t>& shape) {
  using O = std::conditional_t<std::is_void_v<Out>, T, Out>;
  py::array_t<O> out(shape);
  O* p = out.mutable_data();
  for (std::size_t i = 0; i < v.size(); ++i) p[i] = static_cast<O>(v[i]);
  return out;
}

// fn(value) for every value of `in` (any shape), as a new float64 array of
// in's shape; runs in parallel with the GIL released (fn must not touch
// Python).
template <typename Fn>
py::array_t<double> MapValues(const DoubleArray& in, Fn fn) {
  py::array_t<double> out(in.request().shape);
  const double* src = in.data();
  double* dst = out.mutable_data();
  const std::size_t n = static_cast<std::size_t>(in.size());
  {
    py::gil_scoped_release release;
    ParallelFor(n, 8192, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) dst[i] = fn(src[i]);
    });
  }
  return out;
}

// The values of a 1-D array (`name` is used in the error otherwise).
template <typename T, int Flags>
std::vector<T> ToVector(const py::array_t<T, Flags>& a, const char* name) {
  CheckNdim(a, 1, name);
  return std::vector<T>(a.data(), a.data() + a.size());
}

// The values of a C-contiguous array of any shape, in C order.
template <typename T, int Flags>
std::vector<T> FlatVector(const py::array_t<T, Flags>& a) {
  static_assert(Flags & py::array::c_style, "FlatVector needs a C-contiguous array type");
  return std::vector<T>(a.data(), a.data() + a.size());
}

// Arrays a function returns as a dict: New<T>(name, shape) allocates one,
// keeps it under `name` and returns its data for the engine to fill.
class OutputArrays {
 public:
  template <typename T>
  T* New(const char* name, py::array::ShapeContainer shape) {
    py::array_t<T> a(std::move(shape));
    dict_[name] = a;
    return a.mutable_data();
  }
  const py::dict& dict() const { return dict_; }

 private:
  py::dict dict_;
};

// The data of an optional float64 argument (nullptr for None) holding
// `size` values; `keep` holds the converted array. Otherwise throws
// std::invalid_argument "<name> needs <what>; got shape (...)".
const double* OptionalValues(const py::object& value, std::size_t size, const char* name,
                             const std::string& what, DoubleArray* keep);

// --- fields of a bound struct --------------------------------------------------

// A data member of C bound under `name`.
template <typename C, typename M>
struct MemberField {
  using Value = M;
  static constexpr bool kRequired = false;
  const char* name;
  M C::* member;
  const char* doc;

  const M& Get(const C& o) const { return o.*member; }
  void Set(C& o, M v) const { o.*member = std::move(v); }
  template <typename T>
  void Def(py::class_<T>& cls) const {
    cls.def_readwrite(name, member, doc);
  }
};

template <typename C, typename M>
MemberField<C, M> Field(const char* name, M C::* member, const char* doc = nullptr) {
  return {name, member, doc};
}

// A value of C seen by Python as a V through get(const C&) -> V and
// set(C&, const V&).
template <typename C, typename V, typename G, typename S>
struct PropertyField {
  using Value = V;
  static constexpr bool kRequired = false;
  const char* name;
  G get;
  S set;
  const char* doc;

  V Get(const C& o) const { return get(o); }
  void Set(C& o, V v) const { set(o, std::move(v)); }
  template <typename T>
  void Def(py::class_<T>& cls) const {
    cls.def_property(name, get, set, doc);
  }
};

template <typename V, typename C, typename G, typename S>
PropertyField<C, V, G, S> Property(const char* name, G get, S set, const char* doc = nullptr) {
  return {name, get, set, doc};
}

// A field the constructor requires (no default).
template <typename F>
struct RequiredField : F {
  static constexpr bool kRequired = true;
};

template <typename F>
RequiredField<F> Required(F f) {
  return {f};
}

// Whether the constructor takes the fields by keyword only or also by position.
enum class Args { kKeywordOnly, kPositional };

namespace bind_detail {

template <typename T, typename = void>
struct HasCheck : std::false_type {};
template <typename T>
struct HasCheck<T, std::void_t<decltype(std::declval<const T&>().Check())>> : std::true_type {};

// The constructor argument of a field: its default is the field's value in `defaults`.
template <typename F, typename T>
auto ArgOf(const F& f, const T& defaults) {
  if constexpr (F::kRequired)
    return py::arg(f.name);
  else
    return py::arg_v(f.name, f.Get(defaults));
}

// Throws TypeError naming the first keyword that is not a field.
void RejectUnknown(const char* type_name, const py::kwargs& unknown,
                   const std::vector<std::string>& names);

// to_dict, __repr__, __eq__ and the class attribute `fields` over the
// attributes `names` (one definition for every options class).
void DefOptionsMethods(py::object cls, std::vector<std::string> names);

// Sets the attributes of `obj` from a dict (pickle state).
void SetFields(py::object obj, const py::dict& state);

}  // namespace bind_detail

// Binds struct T as a Python class `name` whose attributes are `fields`
// (see the top of this file).
template <typename T, typename... F>
py::class_<T> BindOptions(py::module_& m, const char* name, const char* doc, Args args,
                          F... fields) {
  py::class_<T> cls(m, name, doc);
  const std::vector<std::string> names = {fields.name...};
  auto make = [fields..., name, names](typename F::Value... values, const py::kwargs& unknown) {
    bind_detail::RejectUnknown(name, unknown, names);
    T o;
    (fields.Set(o, std::move(values)), ...);
    if constexpr (bind_detail::HasCheck<T>::value) o.Check();
    return o;
  };
  const T defaults{};
  if (args == Args::kKeywordOnly)
    cls.def(py::init(make), py::kw_only(), bind_detail::ArgOf(fields, defaults)...);
  else
    cls.def(py::init(make), bind_detail::ArgOf(fields, defaults)...);
  (fields.Def(cls), ...);
  if constexpr (bind_detail::HasCheck<T>::value)
    cls.def("check", &T::Check, "Raise ValueError naming the first field out of its range.");
  bind_detail::DefOptionsMethods(cls, names);
  cls.def(py::pickle([](const py::object& self) { return py::dict(self.attr("to_dict")()); },
                     [](const py::dict& state) {
                       py::object obj = py::cast(T{});
                       bind_detail::SetFields(obj, state);
                       return obj.cast<T>();
                     }));
  return cls;
}

// The fields of a result struct as a dict (name -> value).
template <typename T, typename... F>
py::dict ToDict(const T& o, const F&... fields) {
  py::dict d;
  ((d[fields.name] = fields.Get(o)), ...);
  return d;
}

}  // namespace qogi
