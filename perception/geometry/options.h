#pragma once
// One description per options struct. Each struct lists its fields once, in
// `void Describe(OptionVisitor& v)`: key, range and meaning (with the unit). Its validation
// (CheckOptions), the config file's keys, `monoplane config --dump` and the error messages all come
// from that one list, so a range is written in one place.

#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <string>
#include <vector>

namespace monoplane {

// The values a numeric option may take: an interval, open or closed at either end; for integers
// optionally odd values only; with a note on special values ("0 = off").
class OptionRange {
 public:
  static OptionRange Any() { return OptionRange(); }
  static OptionRange AtLeast(double min) { return Make(min, false, kInf, false); }  // >= min
  static OptionRange Above(double min) { return Make(min, true, kInf, false); }     // > min
  static OptionRange Below(double max) { return Make(-kInf, false, max, true); }    // < max
  static OptionRange Closed(double min, double max) { return Make(min, false, max, false); }
  static OptionRange OpenClosed(double min, double max) { return Make(min, true, max, false); }
  static OptionRange Open(double min, double max) { return Make(min, true, max, true); }
  static OptionRange ClosedOpen(double min, double max) { return Make(min, false, max, true); }
  // Integers: odd values only.
  OptionRange Odd() const {
    OptionRange r = *this;
    r.odd_ = true;
    return r;
  }
  // Said after the range in --dump ("0 = off"); not checked.
  OptionRange Note(std::string note) const {
    OptionRange r = *this;
    r.note_ = std::move(note);
    return r;
  }

  // NaN is never in a range; Any() takes every finite value.
  bool Contains(double v) const;
  // ">= 0", "(0, 1]", "odd, >= 5", ">= 0; 0 = off"; empty for Any() without a note.
  std::string Text() const;
  // "must be >= 0", "must be in (0, 1]", "must be odd and >= 5", "must be finite".
  std::string Requirement() const;

 private:
  static constexpr double kInf = std::numeric_limits<double>::infinity();
  static OptionRange Make(double min, bool min_open, double max, bool max_open) {
    OptionRange r;
    r.min_ = min;
    r.min_open_ = min_open;
    r.max_ = max;
    r.max_open_ = max_open;
    return r;
  }
  double min_ = -kInf, max_ = kInf;
  bool min_open_ = false, max_open_ = false, odd_ = false;
  std::string note_;
};

// What a description is read by: a checker, the config file's table, a dump. Keys are the names a
// user writes (snake_case, unit suffix); `meaning` says what the option does, with its unit.
class OptionVisitor {
 public:
  virtual ~OptionVisitor() = default;
  virtual void Real(const std::string& key, double* value, const OptionRange& range,
                    const std::string& meaning) = 0;
  virtual void Real(const std::string& key, float* value, const OptionRange& range,
                    const std::string& meaning) = 0;
  virtual void Integer(const std::string& key, int* value, const OptionRange& range,
                       const std::string& meaning) = 0;
  virtual void Integer(const std::string& key, std::int64_t* value, const OptionRange& range,
                       const std::string& meaning) = 0;
  virtual void Integer(const std::string& key, unsigned* value, const OptionRange& range,
                       const std::string& meaning) = 0;
  virtual void Flag(const std::string& key, bool* value, const std::string& meaning) = 0;
  virtual void Text(const std::string& key, std::string* value, const std::string& meaning) = 0;
  // One of `names`; the field holds the index (an enum's value).
  virtual void Choice(const std::string& key, const std::function<int()>& get,
                      const std::function<void(int)>& set, const std::vector<std::string>& names,
                      const std::string& meaning) = 0;
  // A condition between fields, reported on `key` ("must be > strip_min_x_m"); read after the
  // fields it relates. Only checkers look at it.
  virtual void Rule(bool /*holds*/, const std::string& /*key*/,
                    const std::string& /*requirement*/) {}
};

// Forwards the fields a struct describes under the names an enclosing struct gives them
// ({"min_score", "loop_min_score"}), their meanings after `meaning_prefix`, and drops the others:
// for a nested options struct some of whose fields are set under the enclosing one's keys (the
// nested struct's own IsValid checks the rest).
class RenamedOptions : public OptionVisitor {
 public:
  RenamedOptions(OptionVisitor* to, std::map<std::string, std::string> names,
                 std::string meaning_prefix = "")
      : to_(to), names_(std::move(names)), prefix_(std::move(meaning_prefix)) {}
  void Real(const std::string& key, double* value, const OptionRange& range,
            const std::string& meaning) override;
  void Real(const std::string& key, float* value, const OptionRange& range,
            const std::string& meaning) override;
  void Integer(const std::string& key, int* value, const OptionRange& range,
               const std::string& meaning) override;
  void Integer(const std::string& key, std::int64_t* value, const OptionRange& range,
               const std::string& meaning) override;
  void Integer(const std::string& key, unsigned* value, const OptionRange& range,
               const std::string& meaning) override;
  void Flag(const std::string& key, bool* value, const std::string& meaning) override;
  void Text(const std::string& key, std::string* value, const std::string& meaning) override;
  void Choice(const std::string& key, const std::function<int()>& get,
              const std::function<void(int)>& set, const std::vector<std::string>& names,
              const std::string& meaning) override;
  void Rule(bool holds, const std::string& key, const std::string& requirement) override;

 private:
  const std::string* Find(const std::string& key) const;
  OptionVisitor* to_;
  std::map<std::string, std::string> names_;
  std::string prefix_;
};

// Checks each field against its range, then the rules; stops at the first failure.
class OptionChecker : public OptionVisitor {
 public:
  // Errors name "<prefix>.<key>" (the key alone when prefix is empty).
  explicit OptionChecker(std::string prefix) : prefix_(std::move(prefix)) {}
  // False with "<prefix>.<key>: <value>: <requirement>" (in *error unless null) when something
  // failed.
  bool Ok(std::string* error) const;

  void Real(const std::string& key, double* value, const OptionRange& range,
            const std::string& meaning) override;
  void Real(const std::string& key, float* value, const OptionRange& range,
            const std::string& meaning) override;
  void Integer(const std::string& key, int* value, const OptionRange& range,
               const std::string& meaning) override;
  void Integer(const std::string& key, std::int64_t* value, const OptionRange& range,
               const std::string& meaning) override;
  void Integer(const std::string& key, unsigned* value, const OptionRange& range,
               const std::string& meaning) override;
  void Flag(const std::string& key, bool* value, const std::string& meaning) override;
  void Text(const std::string& key, std::string* value, const std::string& meaning) override;
  void Choice(const std::string& key, const std::function<int()>& get,
              const std::function<void(int)>& set, const std::vector<std::string>& names,
              const std::string& meaning) override;
  void Rule(bool holds, const std::string& key, const std::string& requirement) override;

 private:
  void Number(const std::string& key, double value, const std::string& text,
              const OptionRange& range);
  void Fail(const std::string& key, const std::string& requirement);
  std::string prefix_, error_;
  std::map<std::string, std::string> values_;  // key -> value as text, for rules' messages
};

// The shortest text that reads back as exactly v (0.2, not 0.20000000000000001): config dumps
// stored with each run must give the same options when read again.
std::string FormatOptionValue(double v);
std::string FormatOptionValue(float v);

// Checks options (any struct with Describe(OptionVisitor&)) against their description; on failure
// *error names "<prefix>.<key>", the value and what it must be.
template <typename Options>
bool CheckOptions(const Options& options, const std::string& prefix, std::string* error) {
  Options copy = options;  // Describe binds fields for writing; the checker only reads them
  OptionChecker checker(prefix);
  copy.Describe(checker);
  return checker.Ok(error);
}

// For constructors: `options` when valid (options.IsValid), else aborts with "<who>: <error>" on
// stderr. Invalid options are a caller's error; where they come from users, check IsValid first
// and report it.
[[noreturn]] void DieOfInvalidOptions(const char* who, const std::string& error);
template <typename Options>
const Options& ValidOrDie(const Options& options, const char* who) {
  std::string error;
  if (!options.IsValid(&error)) DieOfInvalidOptions(who, error);
  return options;
}

}  // namespace monoplane
