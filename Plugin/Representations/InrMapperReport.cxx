#include "InrMapperReport.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

std::string InrFormatConvergenceEstimate(double db)
{
  if (std::isnan(db) || db == -std::numeric_limits<double>::infinity())
  {
    return "\u2014";  // not known yet: a covered pixel has a single sample
  }
  if (db == std::numeric_limits<double>::infinity())
  {
    return "no noise left";  // no covered pixel, or no variance
  }
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f dB", db);
  return text;
}

std::string InrDescribeRefinement(const InrMapperReport& r, const InrRefinementLimits& limits)
{
  std::ostringstream s;
  const int frames = r.Frames();
  const double estimate = r.Estimate();
  if (!r.haveEngine || frames == 0)
  {
    s << "\u2014 (nothing rendered yet)";
  }
  else if (r.interactive)
  {
    s << "interacting: reduced " << r.imageWidth << "x" << r.imageHeight << " image";
  }
  else if (!limits.progressive)
  {
    s << "one frame per render (Progressive Refinement off)";
  }
  else if (r.Converged())
  {
    if (limits.convergenceTarget > 0.0 && estimate >= limits.convergenceTarget)
    {
      s << "converged: " << frames << " frames, " << InrFormatConvergenceEstimate(estimate);
    }
    else
    {
      s << "stopped at " << frames << " frames (Maximum Frames " << limits.maximumFrames << ")";
      if (std::isfinite(estimate))
      {
        s << ", " << InrFormatConvergenceEstimate(estimate);
      }
    }
  }
  else
  {
    s << "refining: " << frames << " frames";
    if (std::isfinite(estimate))
    {
      s << ", " << InrFormatConvergenceEstimate(estimate);
      if (limits.convergenceTarget > 0.0)
      {
        char target[32];
        std::snprintf(target, sizeof(target), " of %.0f dB", limits.convergenceTarget);
        s << target;
      }
    }
  }
  return s.str();
}
