// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>

/// One definition of each setting: a settings struct lists its fields once, in
///
///   template <class Archive> void Serialize(Archive* a) {
///     a->Visit("horizon", &horizon, IntIn(1, 100), "N, shooting intervals");
///     a->Nested("qp", &qp);
///   }
///
/// with the key a file uses, what values it accepts and its documentation; the default is
/// the member's initialiser. Readers (fnmpc/config's YAML reader) and writers (the generated
/// key tables of docs/scenarios.md) walk it; the algorithm layers never see a file. A key may
/// hold dots ("bounds.speed"): the field sits in a nested mapping of that name. (The idea is
/// Drake's Serialize/DRAKE_NVP; this is our own minimal version.) C++17: the ROS package
/// compiles some of its units as C++17.
namespace fnmpc {

/// What a field accepts. A reader rejects anything else with `Describe()`'s words and the
/// value; the doc writer prints `Describe()`. Numbers must be finite unless kind is kAny.
struct Limit {
  enum class Kind { kAny, kFinite, kPositive, kNonNegative, kIntRange, kNonNegativeEntries };
  Kind kind = Kind::kAny;
  bool required = false;  ///< a reader rejects a mapping that holds the field's block but not it
  double lo = 0.0, hi = 0.0;  ///< kIntRange: [lo, hi]
  bool say_value = true;      ///< append ", got <value>" to the message
  /// Extra bound checked after `kind`: value < upper (or <= with upper_inclusive), value >=
  /// lower; `unit` ends their message ("must be < 1.2 rad").
  double upper = std::numeric_limits<double>::infinity();
  bool upper_inclusive = false;
  double lower = -std::numeric_limits<double>::infinity();
  const char* unit = "";

  [[nodiscard]] Limit Below(double v, const char* u) const {
    return With(&Limit::upper, v).With(&Limit::upper_inclusive, false).With(&Limit::unit, u);
  }
  [[nodiscard]] Limit AtMost(double v, const char* u) const {
    return With(&Limit::upper, v).With(&Limit::upper_inclusive, true).With(&Limit::unit, u);
  }
  [[nodiscard]] Limit AtLeast(double v, const char* u) const {
    return With(&Limit::lower, v).With(&Limit::unit, u);
  }
  [[nodiscard]] Limit Quiet() const { return With(&Limit::say_value, false); }
  [[nodiscard]] Limit Required() const { return With(&Limit::required, true); }

  /// Empty when `v` is accepted, else what it must be ("must be > 0, got -1").
  [[nodiscard]] std::string Check(double v) const {
    // Built by appending: GCC 12 warns (-Wrestrict, a false positive) on "literal" + string.
    std::string got;
    if (say_value) got.append(", got ").append(std::to_string(v));
    std::string m;
    switch (kind) {
      case Kind::kAny:
        break;
      case Kind::kFinite:
        if (!std::isfinite(v)) return m.append("must be finite");
        break;
      case Kind::kPositive:
        if (!(v > 0.0) || !std::isfinite(v)) return m.append("must be > 0").append(got);
        break;
      case Kind::kNonNegative:
        if (!(v >= 0.0) || !std::isfinite(v)) return m.append("must be >= 0").append(got);
        break;
      case Kind::kNonNegativeEntries:
        if (!(v >= 0.0)) return m.append("weights must be >= 0");
        break;
      case Kind::kIntRange:
        if (!(v >= lo && v <= hi)) {
          return m.append("must be in [")
              .append(Num(lo))
              .append(", ")
              .append(Num(hi))
              .append("]")
              .append(got);
        }
        break;
    }
    if (upper_inclusive ? !(v <= upper) : !(v < upper))
      return m.append(upper_inclusive ? "must be <= " : "must be < ")
          .append(Num(upper))
          .append(Unit());
    if (!(v >= lower)) return m.append("must be >= ").append(Num(lower)).append(Unit());
    return m;
  }

  /// What the field accepts, for the docs ("> 0", "1..100", "> 0, < 1.2 rad"; "" for kAny).
  [[nodiscard]] std::string Describe() const {
    std::string d = required ? "required" : "";
    auto add = [&d](const std::string& what) {
      if (!d.empty()) d.append(", ");
      d.append(what);
    };
    switch (kind) {
      case Kind::kAny:
        break;
      case Kind::kFinite:
        add("finite");
        break;
      case Kind::kPositive:
        add("> 0");
        break;
      case Kind::kNonNegative:
      case Kind::kNonNegativeEntries:
        add("≥ 0");
        break;
      case Kind::kIntRange:
        add(Num(lo) + ".." + Num(hi));
        break;
    }
    if (std::isfinite(upper)) add((upper_inclusive ? "≤ " : "< ") + Num(upper) + Unit());
    if (std::isfinite(lower)) add("≥ " + Num(lower) + Unit());
    return d;
  }

  static std::string Num(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return b;
  }

 private:
  /// A copy with one member changed (the builders above).
  template <class M, class V>
  [[nodiscard]] Limit With(M Limit::*member, V value) const {
    Limit l = *this;
    l.*member = value;
    return l;
  }
  [[nodiscard]] std::string Unit() const {
    std::string u;
    if (*unit != '\0') u.append(" ").append(unit);
    return u;
  }
};

inline Limit AnyValue() { return {}; }
inline Limit Finite() { return {Limit::Kind::kFinite}; }
inline Limit Positive() { return {Limit::Kind::kPositive}; }
inline Limit NonNegative() { return {Limit::Kind::kNonNegative}; }
/// Every entry of a vector >= 0 (weights).
inline Limit NonNegativeEntries() { return {Limit::Kind::kNonNegativeEntries}; }
inline Limit IntIn(int lo, int hi) {
  Limit l{Limit::Kind::kIntRange};
  l.lo = lo;
  l.hi = hi;
  return l;
}

/// A field that takes one name of a fixed list (an enum class whose values are 0, 1, ...):
/// names[i] is value i. The first `available` names are accepted; the later ones are named
/// but rejected as planned, not implemented yet (a reader says so instead of "unknown").
/// Archives visit it with `VisitChoice(key, &enum_field, choice, doc)`.
struct Choice {
  const char* const* names = nullptr;
  int count = 0;
  int available = 0;

  /// Empty and *index set when `name` is accepted, else why not.
  std::string Check(const std::string& name, int* index) const {
    for (int i = 0; i < count; ++i) {
      if (name != names[i]) continue;
      if (i >= available) {
        return std::string("'")
            .append(name)
            .append("' is not implemented yet (accepted: ")
            .append(Accepted())
            .append(")");
      }
      *index = i;
      return {};
    }
    return std::string("must be one of ")
        .append(Accepted())
        .append(", got '")
        .append(name)
        .append("'");
  }
  /// The accepted names, then the planned ones ("none, observer; not implemented yet: wake").
  [[nodiscard]] std::string Describe() const {
    std::string d = Accepted();
    if (available < count) {
      d.append("; not implemented yet: ");
      for (int i = available; i < count; ++i) d.append(i > available ? ", " : "").append(names[i]);
    }
    return d;
  }
  [[nodiscard]] std::string Accepted() const {
    std::string d;
    for (int i = 0; i < available; ++i) d.append(i > 0 ? ", " : "").append(names[i]);
    return d;
  }
};

/// Fields listed by a callable, `list(archive)`: a nested block whose keys depend on where it
/// sits (each sensor of SensorsConfig names its noise channels its own way).
template <class F>
struct FieldList {
  F list;
  template <class Archive>
  void Serialize(Archive* a) {
    list(a);
  }
};
template <class F>
FieldList<F> Fields(F list) {
  return FieldList<F>{list};
}

/// What a [min, max] pair accepts (Serialize's VisitRange): 0 <= min < max (min <= max with
/// `allow_equal`), max < `max_below`; the file gives both in a unit worth `unit_value` of the
/// field's (pi / 180: degrees in the file, radians in the struct).
struct RangeLimit {
  bool allow_equal = false;
  double max_below = std::numeric_limits<double>::infinity();
  const char* unit = "";
  double unit_value = 1.0;

  /// Empty when [lo, hi] (in the file's unit) is accepted, else what it must be.
  [[nodiscard]] std::string Check(double lo, double hi) const {
    if (lo >= 0.0 && (allow_equal ? hi >= lo : hi > lo) && hi < max_below) return "";
    return "must be [min, max] with " + Rule(" <= ", " < ");
  }
  /// What it accepts, for the docs ("0 ≤ min < max").
  [[nodiscard]] std::string Describe() const { return Rule(" ≤ ", " < "); }

 private:
  [[nodiscard]] std::string Rule(const char* at_most, const char* below) const {
    std::string r = std::string("0") + at_most + "min" + (allow_equal ? at_most : below) + "max";
    if (std::isfinite(max_below)) r.append(below).append(Limit::Num(max_below));
    if (*unit != '\0') r.append(" ").append(unit);
    return r;
  }
};

/// Checks a settings struct's numeric fields against their Serialize limits (for structs built
/// in code, not read from a file): throws std::invalid_argument "[<what>] <key> <rule>" at the
/// first field a limit rejects. Choices, ranges and non-numeric fields are not checked here.
class LimitChecker {
 public:
  explicit LimitChecker(const char* what) : what_(what) {}
  template <class T>
  void Visit(const char* key, T* value, const Limit& limit, const char* /*doc*/) {
    if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
      const std::string why = limit.Check(static_cast<double>(*value));
      if (!why.empty()) {
        throw std::invalid_argument(std::string("[") + what_ + "] " + prefix_ + key + " " + why);
      }
    }
  }
  template <class S>
  void Nested(const char* key, S* settings) {
    const std::string outer = prefix_;
    prefix_ += std::string(key) + ".";
    settings->Serialize(this);
    prefix_ = outer;
  }
  template <class E, class C>
  void VisitChoice(const char* /*key*/, E* /*value*/, const C& /*choice*/, const char* /*doc*/) {}
  template <class R>
  void VisitRange(const char* /*key*/, double* /*lo*/, double* /*hi*/, const R& /*limit*/,
                  const char* /*doc*/) {}

 private:
  const char* what_;
  std::string prefix_;
};

/// Runs LimitChecker over `settings`.
template <class S>
void CheckLimits(S& settings, const char* what) {
  LimitChecker checker(what);
  settings.Serialize(&checker);
}

}  // namespace fnmpc
