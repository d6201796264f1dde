// The model's own colour map (MODEL.tf.json beside MODEL.inr) through vtkInrVolumeReader's
// GetTransferFunctionJSON, which ParaView's GUI applies when the model is first shown:
//  - every shipped preset (Testing/Data/real/*.tf.json) comes back verbatim, with no warning;
//  - no file: "" and no warning (the default colour map, nothing to say);
//  - a broken file (not JSON, no RGBPoints, wrong groups, non-finite numbers, opacity outside
//    [0, 1], empty): "" (so the default colour map is used) and exactly one warning naming the
//    file and the problem; asked again unchanged, no second warning; changed, warned again;
//    mended, its text comes back.
// Usage: TestInrReaderTransferFunction MODEL.inr SCRATCH_DIR SHIPPED.tf.json...
#include "vtkCommand.h"
#include "vtkInrVolumeReader.h"
#include "vtkNew.h"

#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace
{
int failures = 0;

void check(bool ok, const std::string& what)
{
  std::cout << (ok ? "ok   " : "FAIL ") << what << std::endl;
  failures += ok ? 0 : 1;
}

std::string readFile(const std::string& path)
{
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void writeFile(const std::string& path, const std::string& text)
{
  std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
}

// Collects the reader's warnings (with an observer VTK hands them to it instead of printing).
class WarningLog : public vtkCommand
{
public:
  static WarningLog* New() { return new WarningLog; }
  void Execute(vtkObject*, unsigned long, void* data) override
  {
    this->Messages.emplace_back(data ? static_cast<const char*>(data) : "");
  }
  std::vector<std::string> Messages;
};

bool contains(const std::string& text, const std::string& part)
{
  return text.find(part) != std::string::npos;
}
} // namespace

int main(int argc, char* argv[])
{
  if (argc < 4)
  {
    std::cerr << "usage: " << argv[0] << " MODEL.inr SCRATCH_DIR SHIPPED.tf.json...\n";
    return 2;
  }
  const std::string scratch = argv[2];
  const std::string model = scratch + "/model.inr";
  const std::string tfPath = scratch + "/model.tf.json";
  writeFile(model, readFile(argv[1]));
  std::remove(tfPath.c_str());

  vtkNew<vtkInrVolumeReader> reader;
  vtkNew<WarningLog> log;
  reader->AddObserver(vtkCommand::WarningEvent, log);
  reader->SetFileName(model.c_str());

  // Shipped presets: verbatim, silent.
  for (int i = 3; i < argc; ++i)
  {
    const std::string preset = readFile(argv[i]);
    writeFile(tfPath, preset);
    log->Messages.clear();
    const std::string got = reader->GetTransferFunctionJSON();
    check(got == preset && log->Messages.empty(),
      std::string("shipped preset ") + argv[i] + ": returned verbatim (" + std::to_string(got.size()) +
        " of " + std::to_string(preset.size()) + " bytes), " + std::to_string(log->Messages.size()) +
        " warnings");
  }

  std::remove(tfPath.c_str());
  log->Messages.clear();
  check(std::string(reader->GetTransferFunctionJSON()).empty() && log->Messages.empty(),
    "no .tf.json: no colour map, no warning");

  struct Case
  {
    const char* name;
    const char* text;
    const char* problem;  // what the warning must say besides the file name
  };
  const Case cases[] = {
    { "not JSON", "[{\"Name\": \"cut\", \"RGBPoints\": [0, 1, 0, 0, 1,", "not valid JSON" },
    { "no RGBPoints", "[{\"Name\": \"x\", \"Points\": [0, 0, 0.5, 0, 1, 1, 0.5, 0]}]",
      "'RGBPoints'" },
    { "a list of numbers", "[0, 0, 0, 1, 1, 1, 0, 0]", "'RGBPoints'" },
    { "RGBPoints not in fours", "[{\"RGBPoints\": [0, 0, 0, 1, 1, 1, 0]}]", "groups of 4" },
    { "RGBPoints holding a string", "[{\"RGBPoints\": [0, 0, 0, \"blue\"]}]", "numbers only" },
    // JSON has no non-finite numbers: the overflowing literal, and NaN as Python's json writes it
    { "overflowing number", "[{\"RGBPoints\": [0, 0, 0, 1, 1e999, 1, 0, 0]}]", "number overflow" },
    { "NaN", "[{\"RGBPoints\": [0, 0, 0, 1, NaN, 1, 0, 0]}]", "non-finite" },
    { "Infinity", "[{\"RGBPoints\": [0, 0, 0, 1, 1, 1, 0, 0], \"Points\": [-Infinity, 0, 0.5, 0]}]",
      "non-finite" },
    { "opacity above 1", "[{\"RGBPoints\": [0, 0, 0, 1, 1, 1, 0, 0], \"Points\": [0, 0, 0.5, 0, 1, 3, 0.5, 0]}]",
      "outside [0, 1]" },
    { "empty file", "", "empty" },
  };
  for (const Case& c : cases)
  {
    writeFile(tfPath, c.text);
    log->Messages.clear();
    const std::string got = reader->GetTransferFunctionJSON();
    const std::string warning = log->Messages.empty() ? "(none)" : log->Messages.front();
    check(got.empty() && log->Messages.size() == 1 && contains(warning, tfPath) &&
        contains(warning, c.problem) && contains(warning, "default colour map"),
      std::string(c.name) + ": no colour map, one warning naming the file, '" + c.problem +
        "' and the default: " + warning);
    // Asked again (ParaView asks more than once per model): no second warning.
    reader->GetTransferFunctionJSON();
    check(log->Messages.size() == 1, std::string(c.name) + ": asked again, no second warning");
  }

  // Changed but still broken: warned again; mended: the text comes back, silently.
  writeFile(tfPath, "{\"RGBPoints\": [0, 0, 0, 1, 1, 1, 0]}");
  log->Messages.clear();
  reader->GetTransferFunctionJSON();
  writeFile(tfPath, "{\"RGBPoints\": [0, 0, 0, 1, 1, 1, 0, 0, 2]}");
  reader->GetTransferFunctionJSON();
  check(log->Messages.size() == 2 && contains(log->Messages.back(), "found 9"),
    "changed and still broken: warned again (" + std::to_string(log->Messages.size()) + " warnings)");
  const std::string mended = "{\"RGBPoints\": [0, 0, 0, 1, 1, 1, 0, 0]}";
  writeFile(tfPath, mended);
  log->Messages.clear();
  check(reader->GetTransferFunctionJSON() == mended && log->Messages.empty(),
    "mended: the text comes back, no warning");

  std::remove(tfPath.c_str());
  std::remove(model.c_str());
  std::cout << (failures ? "FAILED" : "PASS") << std::endl;
  return failures ? 1 : 0;
}
