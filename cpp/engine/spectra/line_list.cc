#include "engine/spectra/line_list.h"

#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <numeric>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "engine/spectra/isotopologue.h"
#include "engine/spectra/json_value.h"
#include "engine/util/check.h"

namespace qogi {

// ---------------------------------------------------------------------------
// LineSelection, LineList

void LineSelection::Check() const {
  Require(!std::isnan(nu_min_cm1) && !std::isnan(nu_max_cm1) && nu_min_cm1 >= 0 &&
              nu_max_cm1 >= nu_min_cm1,
          "line selection: need 0 <= nu_min_cm1 <= nu_max_cm1; got nu_min_cm1 = " +
              FormatNumber(nu_min_cm1) + ", nu_max_cm1 = " + FormatNumber(nu_max_cm1));
  Require(molecule == 0 || IsKnownMolecule(molecule),
          "line selection: molecule must be 0 (any) or a HITRAN molecule code; got " +
              std::to_string(molecule));
  for (int iso : isotopologues)
    Require(iso >= 1, "line selection: isotopologues must be >= 1; got " + std::to_string(iso));
  CheckNonNegative(min_intensity, "line selection: min_intensity", "cm/molecule");
}

bool LineSelection::Keeps(int mol, int iso, double nu, double s) const {
  if (molecule != 0 && mol != molecule) return false;
  if (!(nu >= nu_min_cm1 && nu <= nu_max_cm1)) return false;
  if (s < min_intensity) return false;
  if (!isotopologues.empty() &&
      std::find(isotopologues.begin(), isotopologues.end(), iso) == isotopologues.end())
    return false;
  return true;
}

void LineList::Reserve(std::size_t n) {
  molecule.reserve(n), isotopologue.reserve(n), nu_cm1.reserve(n);
  intensity.reserve(n), einstein_a.reserve(n), gamma_air.reserve(n);
  gamma_self.reserve(n), elower_cm1.reserve(n), n_air.reserve(n);
  n_self.reserve(n), delta_air.reserve(n), delta_self.reserve(n);
}

void LineList::Append(const LineList& o, std::size_t i) {
  molecule.push_back(o.molecule[i]);
  isotopologue.push_back(o.isotopologue[i]);
  nu_cm1.push_back(o.nu_cm1[i]);
  intensity.push_back(o.intensity[i]);
  einstein_a.push_back(o.einstein_a[i]);
  gamma_air.push_back(o.gamma_air[i]);
  gamma_self.push_back(o.gamma_self[i]);
  elower_cm1.push_back(o.elower_cm1[i]);
  n_air.push_back(o.n_air[i]);
  n_self.push_back(o.n_self[i]);
  delta_air.push_back(o.delta_air[i]);
  delta_self.push_back(o.delta_self[i]);
}

void LineList::Check() const {
  const std::size_t n = nu_cm1.size();
  auto same = [&](std::size_t m, const char* name) { CheckSameLength(n, m, "nu_cm1", name); };
  same(molecule.size(), "molecule");
  same(isotopologue.size(), "isotopologue");
  same(intensity.size(), "intensity");
  same(einstein_a.size(), "einstein_a");
  same(gamma_air.size(), "gamma_air");
  same(gamma_self.size(), "gamma_self");
  same(elower_cm1.size(), "elower_cm1");
  same(n_air.size(), "n_air");
  same(n_self.size(), "n_self");
  same(delta_air.size(), "delta_air");
  same(delta_self.size(), "delta_self");
  auto bad = [](const char* name, std::size_t i, const std::string& rule, double v) {
    throw std::invalid_argument(std::string("line list: ") + name + "[" + std::to_string(i) +
                                "] must be " + rule + "; got " + FormatNumber(v));
  };
  for (std::size_t i = 0; i < n; ++i) {
    if (!IsKnownMolecule(molecule[i])) bad("molecule", i, "a HITRAN molecule code", molecule[i]);
    if (isotopologue[i] < 1) bad("isotopologue", i, ">= 1", isotopologue[i]);
    if (!(std::isfinite(nu_cm1[i]) && nu_cm1[i] > 0)) bad("nu_cm1", i, "finite and > 0", nu_cm1[i]);
    if (!(std::isfinite(intensity[i]) && intensity[i] >= 0))
      bad("intensity", i, "finite and >= 0", intensity[i]);
    if (!(std::isfinite(gamma_air[i]) && gamma_air[i] >= 0))
      bad("gamma_air", i, "finite and >= 0", gamma_air[i]);
    if (!(std::isfinite(gamma_self[i]) && gamma_self[i] >= 0))
      bad("gamma_self", i, "finite and >= 0", gamma_self[i]);
    if (!std::isfinite(einstein_a[i])) bad("einstein_a", i, "finite", einstein_a[i]);
    if (!std::isfinite(elower_cm1[i])) bad("elower_cm1", i, "finite", elower_cm1[i]);
    if (!std::isfinite(n_air[i])) bad("n_air", i, "finite", n_air[i]);
    if (!std::isfinite(n_self[i])) bad("n_self", i, "finite", n_self[i]);
    if (!std::isfinite(delta_air[i])) bad("delta_air", i, "finite", delta_air[i]);
    if (!std::isfinite(delta_self[i])) bad("delta_self", i, "finite", delta_self[i]);
  }
}

LineList LineList::Select(const LineSelection& selection) const {
  selection.Check();
  LineList out;
  for (std::size_t i = 0; i < size(); ++i)
    if (selection.Keeps(molecule[i], isotopologue[i], nu_cm1[i], intensity[i]))
      out.Append(*this, i);
  out.coverage = coverage;
  out.sources = sources;
  return out;
}

void LineList::SortByWavenumber() {
  if (std::is_sorted(nu_cm1.begin(), nu_cm1.end())) return;
  std::vector<std::size_t> order(size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return nu_cm1[a] < nu_cm1[b]; });
  LineList sorted;
  sorted.Reserve(size());
  for (std::size_t i : order) sorted.Append(*this, i);
  sorted.coverage = std::move(coverage);
  sorted.sources = std::move(sources);
  *this = std::move(sorted);
}

void LineList::ComputeCoverage() {
  std::map<std::pair<int, int>, std::pair<double, double>> span;
  for (std::size_t i = 0; i < size(); ++i) {
    auto key = std::make_pair(molecule[i], isotopologue[i]);
    auto it = span.find(key);
    if (it == span.end())
      span[key] = {nu_cm1[i], nu_cm1[i]};
    else
      it->second = {std::min(it->second.first, nu_cm1[i]), std::max(it->second.second, nu_cm1[i])};
  }
  coverage.clear();
  for (const auto& kv : span)
    coverage.push_back({kv.first.first, kv.first.second, kv.second.first, kv.second.second});
}

// ---------------------------------------------------------------------------
// Readers

namespace {

enum Slot {
  kMol,
  kIso,
  kNu,
  kSw,
  kA,
  kGammaAir,
  kGammaSelf,
  kElower,
  kNAir,
  kDeltaAir,
  kNSelf,
  kDeltaSelf,
  kNumSlots
};
const char* const kSlotNames[kNumSlots] = {"molec_id", "local_iso_id", "nu",         "sw",
                                           "a",        "gamma_air",    "gamma_self", "elower",
                                           "n_air",    "delta_air",    "n_self",     "delta_self"};
const bool kRequired[kNumSlots] = {true, true, true, true,  false, true,
                                   true, true, true, false, false, false};

struct Column {
  std::string name;
  std::size_t start = 0, width = 0;
};

struct Layout {
  std::vector<Column> fixed;     // every fixed-width column (for messages)
  std::size_t fixed_length = 0;  // characters of the fixed-width part
  int fixed_of[kNumSlots];       // index into `fixed` or -1
  int extra_of[kNumSlots];       // index into `extras` or -1
  std::vector<std::string> extras;
  char separator = ',';
  std::string header_path;       // empty for the plain HITRAN layout
};

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

int SlotOf(const std::string& name) {
  const std::string n = Lower(name);
  for (int s = 0; s < kNumSlots; ++s)
    if (n == kSlotNames[s]) return s;
  return -1;
}

void IndexSlots(Layout& lay) {
  std::fill(std::begin(lay.fixed_of), std::end(lay.fixed_of), -1);
  std::fill(std::begin(lay.extra_of), std::end(lay.extra_of), -1);
  for (std::size_t k = 0; k < lay.fixed.size(); ++k) {
    const int s = SlotOf(lay.fixed[k].name);
    if (s >= 0) lay.fixed_of[s] = static_cast<int>(k);
  }
  for (std::size_t k = 0; k < lay.extras.size(); ++k) {
    const int s = SlotOf(lay.extras[k]);
    if (s >= 0 && lay.fixed_of[s] < 0) lay.extra_of[s] = static_cast<int>(k);
  }
}

// The HITRAN2004+ 160-character record.
Layout HitranLayout() {
  static const std::pair<const char*, std::size_t> cols[] = {{"molec_id", 2},
                                                             {"local_iso_id", 1},
                                                             {"nu", 12},
                                                             {"sw", 10},
                                                             {"a", 10},
                                                             {"gamma_air", 5},
                                                             {"gamma_self", 5},
                                                             {"elower", 10},
                                                             {"n_air", 4},
                                                             {"delta_air", 8},
                                                             {"global_upper_quanta", 15},
                                                             {"global_lower_quanta", 15},
                                                             {"local_upper_quanta", 15},
                                                             {"local_lower_quanta", 15},
                                                             {"ierr", 6},
                                                             {"iref", 12},
                                                             {"line_mixing_flag", 1},
                                                             {"gp", 7},
                                                             {"gpp", 7}};
  Layout lay;
  std::size_t pos = 0;
  for (const auto& c : cols) {
    lay.fixed.push_back({c.first, pos, c.second});
    pos += c.second;
  }
  lay.fixed_length = pos;
  IndexSlots(lay);
  return lay;
}

// Width of a printf-style HAPI format such as "%12.6f" or "%15s".
std::size_t FormatWidth(const std::string& fmt, const std::string& what) {
  std::size_t i = 0;
  if (i < fmt.size() && fmt[i] == '%') ++i;
  std::size_t w = 0, digits = 0;
  while (i < fmt.size() && std::isdigit(static_cast<unsigned char>(fmt[i]))) {
    w = w * 10 + static_cast<std::size_t>(fmt[i] - '0');
    ++i, ++digits;
  }
  if (digits == 0 || w == 0)
    throw std::runtime_error(what + ": format '" + fmt + "' has no field width");
  return w;
}

Layout HeaderLayout(const std::string& header_path, const std::string& text) {
  const JsonValue root = ParseJson(text, header_path);
  if (root.kind != JsonValue::Kind::kObject)
    throw std::runtime_error(header_path + ": a HAPI header must be a JSON object");
  Layout lay;
  lay.header_path = header_path;
  if (const JsonValue* type = root.Find("table_type")) {
    if (type->kind == JsonValue::Kind::kString && type->string != "column-fixed")
      throw std::runtime_error(header_path + ": table_type '" + type->string +
                               "' is not supported (qogi reads 'column-fixed' HAPI tables)");
  }
  const JsonValue* order = root.Find("order");
  const JsonValue* format = root.Find("format");
  const JsonValue* position = root.Find("position");
  if (order && order->kind == JsonValue::Kind::kArray) {
    if (!format || format->kind != JsonValue::Kind::kObject)
      throw std::runtime_error(header_path + ": has 'order' but no 'format' object");
    std::size_t pos = 0;
    for (const JsonValue& name : order->array) {
      if (name.kind != JsonValue::Kind::kString)
        throw std::runtime_error(header_path + ": 'order' must list column names");
      const JsonValue* f = format->Find(name.string);
      if (!f || f->kind != JsonValue::Kind::kString)
        throw std::runtime_error(header_path + ": no format for column '" + name.string + "'");
      const std::size_t width =
          FormatWidth(f->string, header_path + " column '" + name.string + "'");
      std::size_t start = pos;
      if (position) {
        const JsonValue* p = position->Find(name.string);
        if (p && p->kind == JsonValue::Kind::kNumber && p->number >= 0)
          start = static_cast<std::size_t>(p->number);
      }
      lay.fixed.push_back({name.string, start, width});
      pos = start + width;
      lay.fixed_length = std::max(lay.fixed_length, pos);
    }
  }
  if (const JsonValue* extra = root.Find("extra")) {
    if (extra->kind == JsonValue::Kind::kArray)
      for (const JsonValue& name : extra->array)
        if (name.kind == JsonValue::Kind::kString) lay.extras.push_back(name.string);
    if (const JsonValue* sep = root.Find("extra_separator"))
      if (sep->kind == JsonValue::Kind::kString && sep->string.size() == 1)
        lay.separator = sep->string[0];
  }
  IndexSlots(lay);
  for (int s = 0; s < kNumSlots; ++s)
    if (kRequired[s] && lay.fixed_of[s] < 0 && lay.extra_of[s] < 0)
      throw std::runtime_error(
          header_path + ": the table has no column '" + kSlotNames[s] +
          "'; qogi needs molec_id, local_iso_id, nu, sw, gamma_air, gamma_self, "
          "elower and n_air (fetch the table with the HITRAN .par parameters)");
  return lay;
}

// Reads a whole file, gunzipping it when it is gzip data (zlib reads plain
// files unchanged).
std::string ReadAll(const std::string& path) {
  gzFile f = gzopen(path.c_str(), "rb");
  if (!f) throw std::runtime_error("cannot open line file '" + path + "': " + std::strerror(errno));
  gzbuffer(f, 1 << 17);
  std::string data;
  std::vector<char> buf(1 << 20);
  while (true) {
    const int n = gzread(f, buf.data(), static_cast<unsigned>(buf.size()));
    if (n < 0) {
      int err = 0;
      const std::string msg = gzerror(f, &err);
      gzclose(f);
      throw std::runtime_error("cannot read line file '" + path + "': " + msg);
    }
    if (n == 0) break;
    data.append(buf.data(), static_cast<std::size_t>(n));
  }
  int err = 0;
  const char* msg = gzerror(f, &err);
  if (err != Z_OK && err != Z_BUF_ERROR) {
    const std::string m = msg;
    gzclose(f);
    throw std::runtime_error("cannot read line file '" + path + "': " + m);
  }
  if (gzclose(f) != Z_OK)
    throw std::runtime_error("cannot read line file '" + path +
                             "': truncated or corrupt gzip data");
  return data;
}

bool FileExists(const std::string& path) {
  std::ifstream f(path);
  return f.good();
}

// <dir>/<stem>.header for <dir>/<stem>.par[.gz] or <dir>/<stem>.data[.gz].
std::string HeaderPathFor(const std::string& path) {
  std::string stem = path;
  auto strip = [&](const char* ext) {
    const std::size_t n = std::strlen(ext);
    if (stem.size() > n && Lower(stem.substr(stem.size() - n)) == ext) {
      stem.resize(stem.size() - n);
      return true;
    }
    return false;
  };
  strip(".gz");
  if (!strip(".par")) strip(".data");
  return stem + ".header";
}

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

bool IsBlank(std::string_view s) { return Trim(s).empty(); }

class RecordError {
 public:
  RecordError(const std::string& path, std::size_t line) : path_(path), line_(line) {}
  [[noreturn]] void Field(const char* name, const Column* col, const std::string& msg) const {
    std::string where = path_ + ":" + std::to_string(line_) + ": field '" + name + "'";
    if (col)
      where += " (columns " + std::to_string(col->start + 1) + "-" +
               std::to_string(col->start + col->width) + ")";
    throw std::runtime_error(where + ": " + msg);
  }
  [[noreturn]] void Record(const std::string& msg) const {
    throw std::runtime_error(path_ + ":" + std::to_string(line_) + ": " + msg);
  }

 private:
  const std::string& path_;
  std::size_t line_;
};

double ParseDouble(std::string_view field, const char* name, const Column* col,
                   const RecordError& err) {
  const std::string_view t = Trim(field);
  if (t.empty()) err.Field(name, col, "is blank; expected a number");
  std::string_view digits = t;
  if (digits.front() == '+') digits.remove_prefix(1);
  double v = 0;
  const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), v);
  if (r.ec != std::errc() || r.ptr != digits.data() + digits.size() || !std::isfinite(v))
    err.Field(name, col, "not a number: '" + std::string(field) + "'");
  return v;
}

int ParseInt(std::string_view field, const char* name, const Column* col, const RecordError& err) {
  const std::string_view t = Trim(field);
  int v = 0;
  const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
  if (t.empty() || r.ec != std::errc() || r.ptr != t.data() + t.size())
    err.Field(name, col, "not an integer: '" + std::string(field) + "'");
  return v;
}

// HITRAN writes isotopologue numbers 10, 11, 12, ... as '0', 'A', 'B', ...
int ParseIsotopologue(std::string_view field, const Column* col, const RecordError& err) {
  const std::string_view t = Trim(field);
  if (t.size() == 1) {
    const char c = t[0];
    if (c >= '1' && c <= '9') return c - '0';
    if (c == '0') return 10;
    if (c >= 'A' && c <= 'Z') return 11 + (c - 'A');
  } else if (!t.empty()) {
    const int v = ParseInt(t, "local_iso_id", col, err);
    if (v >= 1) return v;
  }
  err.Field("local_iso_id", col,
            "not a HITRAN isotopologue number (1-9, 0 = 10, A = 11, B = 12, ...): '" +
                std::string(field) + "'");
}

LineList ParseRecords(const std::string& path, const std::string& data, const Layout& lay,
                      const LineSelection& sel) {
  LineList out;
  out.Reserve(std::count(data.begin(), data.end(), '\n') + 1);
  std::map<std::pair<int, int>, std::pair<double, double>> span;
  std::vector<std::string_view> extra_fields;
  const std::size_t n = data.size();
  std::size_t pos = 0, line_no = 0;
  while (pos < n) {
    std::size_t end = data.find('\n', pos);
    if (end == std::string::npos) end = n;
    std::string_view rec(data.data() + pos, end - pos);
    pos = end + 1;
    ++line_no;
    while (!rec.empty() && rec.back() == '\r') rec.remove_suffix(1);
    if (IsBlank(rec)) continue;
    const RecordError err(path, line_no);

    if (rec.size() < lay.fixed_length) {
      const Column* cut = nullptr;
      for (const Column& c : lay.fixed)
        if (c.start + c.width > rec.size()) {
          cut = &c;
          break;
        }
      err.Record("truncated record: " + std::to_string(rec.size()) + " characters where the " +
                 (lay.header_path.empty() ? std::string("HITRAN .par format")
                                          : "header " + lay.header_path) +
                 " needs " + std::to_string(lay.fixed_length) +
                 (cut ? " (field '" + cut->name + "' at columns " + std::to_string(cut->start + 1) +
                            "-" + std::to_string(cut->start + cut->width) + " is cut off)"
                      : std::string()));
    }
    std::string_view rest = rec.substr(lay.fixed_length);
    extra_fields.clear();
    if (lay.extras.empty()) {
      if (!IsBlank(rest))
        err.Record(
            "record has " + std::to_string(rec.size()) + " characters; " +
            (lay.header_path.empty()
                 ? std::string("a HITRAN .par record has 160 (for a HAPI .data "
                               "file with extra parameters, put its .header beside it)")
                 : "header " + lay.header_path + " describes " + std::to_string(lay.fixed_length)));
    } else {
      if (lay.fixed_length > 0) {
        if (rest.empty() || rest.front() != lay.separator)
          err.Record(std::string("expected '") + lay.separator +
                     "' and the extra parameters after column " + std::to_string(lay.fixed_length));
        rest.remove_prefix(1);
      }
      while (true) {
        const std::size_t k = rest.find(lay.separator);
        extra_fields.push_back(rest.substr(0, k));
        if (k == std::string_view::npos) break;
        rest.remove_prefix(k + 1);
      }
      if (extra_fields.size() < lay.extras.size())
        err.Record("has " + std::to_string(extra_fields.size()) + " extra parameters; header " +
                   lay.header_path + " lists " + std::to_string(lay.extras.size()));
    }

    // Raw text of a slot, or nullopt-like (found = false) when absent/missing.
    auto text = [&](int slot, const Column*& col, bool& found) -> std::string_view {
      col = nullptr;
      found = false;
      if (lay.fixed_of[slot] >= 0) {
        col = &lay.fixed[static_cast<std::size_t>(lay.fixed_of[slot])];
        found = true;
        return rec.substr(col->start, col->width);
      }
      if (lay.extra_of[slot] >= 0) {
        std::string_view v = extra_fields[static_cast<std::size_t>(lay.extra_of[slot])];
        const std::string_view t = Trim(v);
        found = !(t.empty() || t == "#");
        return v;
      }
      return {};
    };
    auto number = [&](int slot, double fallback) {
      const Column* col;
      bool found;
      const std::string_view t = text(slot, col, found);
      if (!found) {
        if (kRequired[slot]) err.Field(kSlotNames[slot], col, "is missing");
        return fallback;
      }
      return ParseDouble(t, kSlotNames[slot], col, err);
    };

    const Column* col;
    bool found;
    const std::string_view mol_text = text(kMol, col, found);
    if (!found) err.Field("molec_id", col, "is missing");
    const int mol = ParseInt(mol_text, "molec_id", col, err);
    if (!IsKnownMolecule(mol))
      err.Field("molec_id", col,
                "unknown HITRAN molecule code " + std::to_string(mol) +
                    " (is this a HITRAN .par/.data file?)");
    const std::string_view iso_text = text(kIso, col, found);
    if (!found) err.Field("local_iso_id", col, "is missing");
    const int iso = ParseIsotopologue(iso_text, col, err);

    const double nu = number(kNu, 0);
    const double s = number(kSw, 0);
    const double a = number(kA, 0);
    const double g_air = number(kGammaAir, 0);
    const double g_self = number(kGammaSelf, 0);
    const double elower = number(kElower, 0);
    const double n_air = number(kNAir, 0);
    const double d_air = number(kDeltaAir, 0);
    const double n_self = number(kNSelf, n_air);
    const double d_self = number(kDeltaSelf, d_air);
    auto check = [&](int slot, bool ok, const char* rule, double v) {
      if (ok) return;
      const Column* c = lay.fixed_of[slot] >= 0
                            ? &lay.fixed[static_cast<std::size_t>(lay.fixed_of[slot])]
                            : nullptr;
      err.Field(kSlotNames[slot], c, std::string("must be ") + rule + "; got " + FormatNumber(v));
    };
    check(kNu, nu > 0, "> 0 cm-1", nu);
    check(kSw, s >= 0, ">= 0", s);
    check(kGammaAir, g_air >= 0, ">= 0", g_air);
    check(kGammaSelf, g_self >= 0, ">= 0", g_self);

    auto key = std::make_pair(mol, iso);
    auto it = span.find(key);
    if (it == span.end())
      span.emplace(key, std::make_pair(nu, nu));
    else
      it->second = {std::min(it->second.first, nu), std::max(it->second.second, nu)};

    if (!sel.Keeps(mol, iso, nu, s)) continue;
    out.molecule.push_back(mol);
    out.isotopologue.push_back(iso);
    out.nu_cm1.push_back(nu);
    out.intensity.push_back(s);
    out.einstein_a.push_back(a);
    out.gamma_air.push_back(g_air);
    out.gamma_self.push_back(g_self);
    out.elower_cm1.push_back(elower);
    out.n_air.push_back(n_air);
    out.n_self.push_back(n_self);
    out.delta_air.push_back(d_air);
    out.delta_self.push_back(d_self);
  }
  for (const auto& kv : span)
    if (sel.molecule == 0 || kv.first.first == sel.molecule)
      out.coverage.push_back({kv.first.first, kv.first.second, kv.second.first, kv.second.second});
  out.sources.push_back(path);
  return out;
}

}  // namespace

LineList ReadLineFile(const std::string& path, const LineSelection& selection) {
  selection.Check();
  const std::string data = ReadAll(path);
  const std::string header = HeaderPathFor(path);
  Layout layout;
  if (FileExists(header))
    layout = HeaderLayout(header, ReadAll(header));
  else
    layout = HitranLayout();
  LineList lines = ParseRecords(path, data, layout, selection);
  lines.SortByWavenumber();
  return lines;
}

LineList ReadLineFiles(const std::vector<std::string>& paths, const LineSelection& selection) {
  Require(!paths.empty(), "ReadLineFiles: paths must list at least one file");
  std::vector<LineList> lists;
  lists.reserve(paths.size());
  for (const std::string& p : paths) lists.push_back(ReadLineFile(p, selection));
  if (lists.size() == 1) return std::move(lists.front());
  return MergeLineLists(lists);
}

LineList MergeLineLists(const std::vector<LineList>& by_priority) {
  LineList out;
  std::vector<LineCoverage> covered;
  std::size_t total = 0;
  for (const LineList& l : by_priority) total += l.size();
  out.Reserve(total);
  for (const LineList& list : by_priority) {
    list.Check();
    std::vector<LineCoverage> own = list.coverage;
    if (own.empty() && !list.empty()) {
      LineList tmp;
      tmp.nu_cm1 = list.nu_cm1, tmp.molecule = list.molecule, tmp.isotopologue = list.isotopologue;
      tmp.ComputeCoverage();
      own = tmp.coverage;
    }
    for (std::size_t i = 0; i < list.size(); ++i) {
      bool dup = false;
      for (const LineCoverage& c : covered)
        if (c.molecule == list.molecule[i] && c.isotopologue == list.isotopologue[i] &&
            list.nu_cm1[i] >= c.nu_min_cm1 && list.nu_cm1[i] <= c.nu_max_cm1) {
          dup = true;
          break;
        }
      if (!dup) out.Append(list, i);
    }
    for (LineCoverage c : own) {
      c.source += static_cast<int>(out.sources.size());
      covered.push_back(c);
    }
    out.sources.insert(out.sources.end(), list.sources.begin(), list.sources.end());
    if (list.sources.empty()) out.sources.push_back("<memory>");
  }
  out.coverage = covered;
  out.SortByWavenumber();
  return out;
}

}  // namespace qogi
