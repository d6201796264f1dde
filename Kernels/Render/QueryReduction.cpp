#include "Render/QueryReduction.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace inr {

BudgetScheme parseBudgetScheme(const std::string& name) {
  std::string s = name;
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (s == "none" || s == "off") return BudgetScheme::None;
  if (s == "histogram") return BudgetScheme::Histogram;
  if (s == "stbn") return BudgetScheme::Stbn;
  if (s == "weighted-stbn" || s == "weighted_stbn") return BudgetScheme::WeightedStbn;
  throw std::invalid_argument("unknown ray budgeting scheme '" + name +
                              "' (choose none, histogram, stbn or weighted-stbn)");
}

const char* budgetSchemeName(BudgetScheme scheme) {
  switch (scheme) {
    case BudgetScheme::None: return "none";
    case BudgetScheme::Histogram: return "histogram";
    case BudgetScheme::Stbn: return "stbn";
    case BudgetScheme::WeightedStbn: return "weighted-stbn";
  }
  return "unknown";
}

void QueryReductionSettings::validate() const {
  auto fail = [](const char* name, double v, const char* range) {
    std::ostringstream m;
    m << "query reduction: " << name << " = " << v << " is out of range (" << range << ")";
    throw std::invalid_argument(m.str());
  };
  if (int(budget) < 0 || int(budget) > 3) fail("budget scheme", double(int(budget)), "0..3");
  if (!(budgetFraction > 0.0 && budgetFraction <= 1.0)) fail("budget fraction (rho)", budgetFraction, "(0, 1]");
  if (budgetMaxSkip < 0 || budgetMaxSkip > 1024) fail("budget max skip (K)", budgetMaxSkip, "0..1024 frames");
  if (!(budgetAlpha >= 0.0 && budgetAlpha <= 1.0)) fail("budget alpha", budgetAlpha, "[0, 1]");
  if (reprojectHistory < 1 || reprojectHistory > 1 << 20) fail("reprojection history", reprojectHistory, "1..2^20 frames");
  if (!(pruneEpsilon >= 0.0 && pruneEpsilon <= 1.0)) fail("prune epsilon", pruneEpsilon, "[0, 1] of the value range");
  if (!(pruneFalloff >= 0.0 && pruneFalloff <= 1.0)) fail("prune falloff (delta)", pruneFalloff, "[0, 1] of the value range");
}

}  // namespace inr
