#include "perception/geometry/options.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace monoplane {
namespace {

std::string Bound(double v) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return FormatOptionValue(v);
}

template <typename T>
std::string ShortestText(T v) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), v);
  return std::string(buffer, result.ptr);
}

}  // namespace

void DieOfInvalidOptions(const char* who, const std::string& error) {
  std::fprintf(stderr, "%s: %s\n", who, error.c_str());
  std::abort();
}

std::string FormatOptionValue(double v) { return ShortestText(v); }
std::string FormatOptionValue(float v) { return ShortestText(v); }

bool OptionRange::Contains(double v) const {
  if (!std::isfinite(v)) return false;
  if (min_open_ ? !(v > min_) : !(v >= min_)) return false;
  if (max_open_ ? !(v < max_) : !(v <= max_)) return false;
  return !odd_ || std::fmod(std::abs(v), 2.0) == 1.0;
}

std::string OptionRange::Text() const {
  std::string text;
  const bool has_min = !std::isinf(min_), has_max = !std::isinf(max_);
  if (has_min && has_max) {
    text = std::string(min_open_ ? "(" : "[") + Bound(min_) + ", " + Bound(max_) +
           (max_open_ ? ")" : "]");
  } else if (has_min) {
    text = std::string(min_open_ ? "> " : ">= ") + Bound(min_);
  } else if (has_max) {
    text = std::string(max_open_ ? "< " : "<= ") + Bound(max_);
  }
  if (odd_) text = text.empty() ? "odd" : "odd, " + text;
  if (!note_.empty()) text += (text.empty() ? "" : "; ") + note_;
  return text;
}

std::string OptionRange::Requirement() const {
  const bool has_min = !std::isinf(min_), has_max = !std::isinf(max_);
  std::string relation;
  if (has_min && has_max) {
    relation = "in " + std::string(min_open_ ? "(" : "[") + Bound(min_) + ", " + Bound(max_) +
               (max_open_ ? ")" : "]");
  } else if (has_min) {
    relation = std::string(min_open_ ? "> " : ">= ") + Bound(min_);
  } else if (has_max) {
    relation = std::string(max_open_ ? "< " : "<= ") + Bound(max_);
  } else {
    relation = "finite";
  }
  return "must be " + std::string(odd_ ? "odd and " : "") + relation;
}

const std::string* RenamedOptions::Find(const std::string& key) const {
  const auto it = names_.find(key);
  return it == names_.end() ? nullptr : &it->second;
}

void RenamedOptions::Real(const std::string& key, double* value, const OptionRange& range,
                          const std::string& meaning) {
  if (const std::string* name = Find(key)) to_->Real(*name, value, range, prefix_ + meaning);
}
void RenamedOptions::Real(const std::string& key, float* value, const OptionRange& range,
                          const std::string& meaning) {
  if (const std::string* name = Find(key)) to_->Real(*name, value, range, prefix_ + meaning);
}
void RenamedOptions::Integer(const std::string& key, int* value, const OptionRange& range,
                             const std::string& meaning) {
  if (const std::string* name = Find(key)) to_->Integer(*name, value, range, prefix_ + meaning);
}
void RenamedOptions::Integer(const std::string& key, std::int64_t* value, const OptionRange& range,
                             const std::string& meaning) {
  if (const std::string* name = Find(key)) to_->Integer(*name, value, range, prefix_ + meaning);
}
void RenamedOptions::Integer(const std::string& key, unsigned* value, const OptionRange& range,
                             const std::string& meaning) {
  if (const std::string* name = Find(key)) to_->Integer(*name, value, range, prefix_ + meaning);
}
void RenamedOptions::Flag(const std::string& key, bool* value, const std::string& meaning) {
  if (const std::string* name = Find(key)) to_->Flag(*name, value, prefix_ + meaning);
}
void RenamedOptions::Text(const std::string& key, std::string* value, const std::string& meaning) {
  if (const std::string* name = Find(key)) to_->Text(*name, value, prefix_ + meaning);
}
void RenamedOptions::Choice(const std::string& key, const std::function<int()>& get,
                            const std::function<void(int)>& set,
                            const std::vector<std::string>& names, const std::string& meaning) {
  if (const std::string* name = Find(key)) to_->Choice(*name, get, set, names, prefix_ + meaning);
}
void RenamedOptions::Rule(bool holds, const std::string& key, const std::string& requirement) {
  if (const std::string* name = Find(key)) to_->Rule(holds, *name, requirement);
}

bool OptionChecker::Ok(std::string* error) const {
  if (error_.empty()) return true;
  if (error) *error = error_;
  return false;
}

void OptionChecker::Fail(const std::string& key, const std::string& requirement) {
  if (!error_.empty()) return;
  const auto value = values_.find(key);
  error_ = (prefix_.empty() ? key : prefix_ + "." + key) + ": " +
           (value == values_.end() ? "" : value->second + ": ") + requirement;
}

void OptionChecker::Number(const std::string& key, double value, const std::string& text,
                           const OptionRange& range) {
  values_[key] = text;
  if (!range.Contains(value)) Fail(key, range.Requirement());
}

void OptionChecker::Real(const std::string& key, double* value, const OptionRange& range,
                         const std::string&) {
  Number(key, *value, FormatOptionValue(*value), range);
}
void OptionChecker::Real(const std::string& key, float* value, const OptionRange& range,
                         const std::string&) {
  Number(key, *value, FormatOptionValue(*value), range);
}
void OptionChecker::Integer(const std::string& key, int* value, const OptionRange& range,
                            const std::string&) {
  Number(key, *value, std::to_string(*value), range);
}
void OptionChecker::Integer(const std::string& key, std::int64_t* value, const OptionRange& range,
                            const std::string&) {
  Number(key, static_cast<double>(*value), std::to_string(*value), range);
}
void OptionChecker::Integer(const std::string& key, unsigned* value, const OptionRange& range,
                            const std::string&) {
  Number(key, *value, std::to_string(*value), range);
}
void OptionChecker::Flag(const std::string& key, bool* value, const std::string&) {
  values_[key] = *value ? "true" : "false";
}
void OptionChecker::Text(const std::string& key, std::string* value, const std::string&) {
  values_[key] = "'" + *value + "'";
}
void OptionChecker::Choice(const std::string& key, const std::function<int()>& get,
                           const std::function<void(int)>&, const std::vector<std::string>& names,
                           const std::string&) {
  const int v = get();
  if (v < 0 || v >= static_cast<int>(names.size())) {
    values_[key] = std::to_string(v);
    std::string list;
    for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
    Fail(key, "must be one of " + list);
    return;
  }
  values_[key] = names[static_cast<std::size_t>(v)];
}
void OptionChecker::Rule(bool holds, const std::string& key, const std::string& requirement) {
  if (!holds) Fail(key, requirement);
}

}  // namespace monoplane
