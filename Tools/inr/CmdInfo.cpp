#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "Args.h"
#include "Commands.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"

namespace inr::cli {
namespace {

const char* kCoord = "xyzt";

nlohmann::json describe(const InrModel& m, const SampledRange& sampled) {
  nlohmann::json j;
  j["file"] = m.path;
  j["name"] = m.name;
  j["description"] = m.description;
  j["provenance"] = m.provenance;
  j["architecture"] = m.architecture.summary();
  j["input_dim"] = m.architecture.inputDim;
  j["max_width"] = m.architecture.maxWidth();
  j["parameters"] = m.architecture.parameterCount();
  j["bounds"] = m.domain.bounds;
  j["time_range"] = {m.domain.timeBegin, m.domain.timeEnd};
  j["time_dependent"] = m.domain.usesTime();
  std::string order;
  for (int c : m.domain.inputOrder) order += kCoord[c];
  j["input_order"] = order;
  for (int c = 0; c < 4; ++c)
    j["world_to_network"][std::string(1, kCoord[c])] = {m.domain.toNetwork[c].scale, m.domain.toNetwork[c].offset};
  j["time_steps"] = m.domain.timeSteps;
  if (m.output.perTime)
    j["output"] = {{"per_time_entries", m.output.perTime->times.size()}};
  else
    j["output"] = {{"scale", m.output.scale}, {"offset", m.output.offset}};
  if (m.valueRange) j["value_range_hint"] = *m.valueRange;
  j["sampled_value_range"] = {{"min", sampled.min}, {"max", sampled.max}, {"samples", sampled.samples}};
  return j;
}

}  // namespace

int runInfo(int argc, char** argv) {
  Args args(argc, argv, {}, {"json", "help"});
  if (args.has("help")) {
    std::puts("usage: inr info MODEL [--json]\n"
              "Prints the architecture, parameter count, domain (world box, time range, input mapping),\n"
              "output mapping, the value-range hint and the range sampled on a 16^3 x 5 lattice.");
    return 0;
  }
  if (args.positional().size() != 1) throw UsageError("expects exactly one MODEL file");
  const InrModel model = InrModel::loadFile(args.positional()[0]);
  const CpuInrEvaluator evaluator(model);
  const SampledRange sampled = sampleValueRange(evaluator, model.domain, 16, 5);
  const nlohmann::json j = describe(model, sampled);
  if (args.has("json")) {
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  const auto& d = model.domain;
  std::printf("file:          %s\n", model.path.c_str());
  if (!model.name.empty()) std::printf("name:          %s\n", model.name.c_str());
  if (!model.description.empty()) std::printf("description:   %s\n", model.description.c_str());
  if (!model.provenance.empty()) std::printf("provenance:    %s\n", model.provenance.c_str());
  std::printf("architecture:  %s\n", model.architecture.summary().c_str());
  std::printf("inputs:        %d (%s), max width %d\n", model.architecture.inputDim,
              j["input_order"].get<std::string>().c_str(), model.architecture.maxWidth());
  std::printf("parameters:    %zu (%.1f KB as fp32)\n", model.architecture.parameterCount(),
              model.architecture.parameterCount() * 4.0 / 1024.0);
  std::printf("bounds:        x [%g, %g]  y [%g, %g]  z [%g, %g]\n", d.bounds[0], d.bounds[1], d.bounds[2],
              d.bounds[3], d.bounds[4], d.bounds[5]);
  std::printf("time range:    [%g, %g]%s\n", d.timeBegin, d.timeEnd, d.usesTime() ? "" : " (static model)");
  if (!d.timeSteps.empty()) std::printf("time steps:    %zu hints\n", d.timeSteps.size());
  if (model.output.perTime)
    std::printf("output:        per-time normalisation, %zu entries\n", model.output.perTime->times.size());
  else
    std::printf("output:        %g * net + %g\n", model.output.scale, model.output.offset);
  if (model.valueRange) std::printf("value range:   [%g, %g] (hint)\n", (*model.valueRange)[0], (*model.valueRange)[1]);
  std::printf("sampled range: [%g, %g] (%zu samples)\n", sampled.min, sampled.max, sampled.samples);
  return 0;
}

}  // namespace inr::cli
