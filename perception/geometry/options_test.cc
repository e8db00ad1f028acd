#include "perception/geometry/options.h"

#include <gtest/gtest.h>

#include <cmath>

namespace monoplane {
namespace {

struct Inner {
  double gain = 0.5;
  int hidden = 3;
  void Describe(OptionVisitor& v) {
    v.Real("gain", &gain, OptionRange::OpenClosed(0, 1), "gain");
    v.Integer("hidden", &hidden, OptionRange::AtLeast(1), "not set from outside");
  }
};

struct Outer {
  double low_m = 0.0, high_m = 1.0;
  int window_px = 5;
  Inner inner;
  void Describe(OptionVisitor& v) {
    v.Real("low_m", &low_m, OptionRange::AtLeast(0), "low, m");
    v.Real("high_m", &high_m, OptionRange::Any().Note("> low_m"), "high, m");
    v.Rule(high_m > low_m, "high_m", "must be > low_m");
    v.Integer("window_px", &window_px, OptionRange::AtLeast(3).Odd(), "window, px");
    RenamedOptions renamed(&v, {{"gain", "inner_gain"}}, "inner: ");
    inner.Describe(renamed);
  }
};

TEST(OptionRange, TextRequirementAndMembership) {
  EXPECT_EQ(OptionRange::AtLeast(0).Text(), ">= 0");
  EXPECT_EQ(OptionRange::Above(0).Requirement(), "must be > 0");
  EXPECT_EQ(OptionRange::OpenClosed(0, 1).Text(), "(0, 1]");
  EXPECT_EQ(OptionRange::Closed(0.005, 1).Requirement(), "must be in [0.005, 1]");
  EXPECT_EQ(OptionRange::AtLeast(5).Odd().Text(), "odd, >= 5");
  EXPECT_EQ(OptionRange::AtLeast(5).Odd().Requirement(), "must be odd and >= 5");
  EXPECT_EQ(OptionRange::AtLeast(0).Note("0 = off").Text(), ">= 0; 0 = off");
  EXPECT_EQ(OptionRange::Any().Text(), "");
  EXPECT_EQ(OptionRange::Any().Requirement(), "must be finite");

  EXPECT_TRUE(OptionRange::OpenClosed(0, 1).Contains(1));
  EXPECT_FALSE(OptionRange::OpenClosed(0, 1).Contains(0));
  EXPECT_FALSE(OptionRange::ClosedOpen(0, 90).Contains(90));
  EXPECT_FALSE(OptionRange::Any().Contains(NAN));
  EXPECT_FALSE(OptionRange::Any().Contains(INFINITY));
  EXPECT_FALSE(OptionRange::AtLeast(0).Contains(NAN));
  EXPECT_TRUE(OptionRange::AtLeast(3).Odd().Contains(7));
  EXPECT_FALSE(OptionRange::AtLeast(3).Odd().Contains(8));
}

TEST(CheckOptions, NamesTheKeyTheValueAndTheRequirement) {
  std::string error;
  EXPECT_TRUE(CheckOptions(Outer(), "section", &error)) << error;
  Outer o;
  o.low_m = -1;
  EXPECT_FALSE(CheckOptions(o, "section", &error));
  EXPECT_EQ(error, "section.low_m: -1: must be >= 0");
  o = Outer();
  o.window_px = 4;
  EXPECT_FALSE(CheckOptions(o, "section", &error));
  EXPECT_EQ(error, "section.window_px: 4: must be odd and >= 3");
  // A rule between fields is reported on its key, with that key's value.
  o = Outer();
  o.high_m = 0;
  EXPECT_FALSE(CheckOptions(o, "section", &error));
  EXPECT_EQ(error, "section.high_m: 0: must be > low_m");
  // A nested field under the name the enclosing struct gives it; one it leaves out is not checked
  // there (the nested struct's own check covers it).
  o = Outer();
  o.inner.gain = 2;
  EXPECT_FALSE(CheckOptions(o, "section", &error));
  EXPECT_EQ(error, "section.inner_gain: 2: must be in (0, 1]");
  o = Outer();
  o.inner.hidden = 0;
  EXPECT_TRUE(CheckOptions(o, "section", &error));
  EXPECT_FALSE(CheckOptions(o.inner, "inner", &error));
  EXPECT_EQ(error, "inner.hidden: 0: must be >= 1");
  // NaN is in no range; the first failure is the one reported.
  o = Outer();
  o.low_m = NAN;
  o.window_px = 2;
  EXPECT_FALSE(CheckOptions(o, "", &error));
  EXPECT_EQ(error, "low_m: nan: must be >= 0");
  EXPECT_FALSE(CheckOptions(o, "", nullptr));
}

// What a table of keys sees: every field once, renamed ones under their new names and meanings.
class KeyLister : public OptionVisitor {
 public:
  std::vector<std::string> keys;
  void Real(const std::string& k, double*, const OptionRange& r, const std::string& m) override {
    keys.push_back(k + " | " + m + " | " + r.Text());
  }
  void Real(const std::string& k, float*, const OptionRange&, const std::string&) override {
    keys.push_back(k);
  }
  void Integer(const std::string& k, int*, const OptionRange& r, const std::string& m) override {
    keys.push_back(k + " | " + m + " | " + r.Text());
  }
  void Integer(const std::string& k, std::int64_t*, const OptionRange&,
               const std::string&) override {
    keys.push_back(k);
  }
  void Integer(const std::string& k, unsigned*, const OptionRange&, const std::string&) override {
    keys.push_back(k);
  }
  void Flag(const std::string& k, bool*, const std::string&) override { keys.push_back(k); }
  void Text(const std::string& k, std::string*, const std::string&) override { keys.push_back(k); }
  void Choice(const std::string& k, const std::function<int()>&, const std::function<void(int)>&,
              const std::vector<std::string>&, const std::string&) override {
    keys.push_back(k);
  }
};

TEST(RenamedOptions, ForwardsOnlyTheNamedFields) {
  Outer o;
  KeyLister lister;
  o.Describe(lister);
  EXPECT_EQ(lister.keys,
            (std::vector<std::string>{"low_m | low, m | >= 0", "high_m | high, m | > low_m",
                                      "window_px | window, px | odd, >= 3",
                                      "inner_gain | inner: gain | (0, 1]"}));
}

}  // namespace
}  // namespace monoplane
