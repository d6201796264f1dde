// No growth through the ParaView mapper (issue 13, item 6): vtkInrVolumeMapper (CPU backend) in a
// plain VTK render window, 1000 time changes through the reader and 1000 edits of the volume
// property's transfer function (colour, scalar opacity, unit distance), one Render() each. The
// resident set (/proc/self/statm) may not grow by more than kBoundMiB after the first 100 changes
// of each kind (warm-up: slices built lazily, the driver's and allocators' pools), the engine is
// built once and every render shows the volume. A step of the resident set after the warm-up
// names the mappings that grew (/proc/self/smaps: a heap arena, a driver's mapping, ...), so
// that a run on another machine (issue 52, item 4: the many-core host's step) says what it was.
// Usage: TestInrMapperNoGrowth MODEL.inr [--changes N] [--leak-kib K]
// --leak-kib K (the control): every time change also leaks K KiB, touched, so that the checks
// must fail and the step's report must name the heap.
#include "InrPluginTestChecks.h"
#include "vtkColorTransferFunction.h"
#include "vtkInrVolumeMapper.h"
#include "vtkInrVolumeReader.h"
#include "vtkNew.h"
#include "vtkPiecewiseFunction.h"
#include "vtkRenderWindow.h"
#include "vtkRenderer.h"
#include "vtkVolume.h"
#include "vtkVolumeProperty.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace
{
const double kBoundMiB = 8.0;

double residentMiB()
{
  std::ifstream f("/proc/self/statm");
  double size = 0, resident = 0;
  f >> size >> resident;
  return resident * 4096.0 / (1024.0 * 1024.0);
}

// Resident KiB of /proc/self/smaps summed per mapped name ("[heap]", a library, a driver's
// device file; "anonymous" for the unnamed mappings: mmap'd blocks and the heaps of threads'
// malloc arenas): where a step of the resident set happened, printed when one happens so that a
// run on another machine says what grew.
std::map<std::string, long> residentByMapping()
{
  std::map<std::string, long> out;
  std::ifstream f("/proc/self/smaps");
  std::string line, name;
  while (std::getline(f, line))
  {
    const std::size_t dash = line.find('-');
    if (!line.empty() && std::isxdigit(static_cast<unsigned char>(line[0])) && dash != std::string::npos &&
      line.find(':') > dash + 1 && line.compare(0, 4, "Rss:") != 0)
    {
      // "start-end perms offset dev inode [name]": the sixth field, if any.
      std::istringstream in(line);
      std::string field;
      name = "anonymous";
      for (int i = 0; in >> field; ++i)
      {
        if (i == 5)
        {
          name = field;
        }
      }
    }
    else if (line.compare(0, 4, "Rss:") == 0)
    {
      std::istringstream in(line.substr(4));
      long kib = 0;
      in >> kib;
      out[name] += kib;
    }
  }
  return out;
}

// The names whose resident size grew by more than 256 KiB between two snapshots.
void printGrowth(const std::map<std::string, long>& before, const std::map<std::string, long>& after)
{
  for (const auto& [mapping, kib] : after)
  {
    const auto was = before.find(mapping);
    const long grew = kib - (was == before.end() ? 0 : was->second);
    if (grew > 256)
    {
      std::printf("  grew %ld KiB: %s\n", grew, mapping.c_str());
    }
  }
}

using inr_plugin_test::check;
using inr_plugin_test::failures;

// Edit k of the transfer function: the opacity ramp's top, a node's midpoint/sharpness, a colour
// point and the unit distance all move; every third edit has one node more.
void editTransferFunction(vtkVolumeProperty* prop, vtkColorTransferFunction* ctf,
  vtkPiecewiseFunction* otf, const double range[2], int k)
{
  const double lo = range[0], hi = range[1], span = hi - lo;
  otf->RemoveAllPoints();
  otf->AddPoint(lo + 0.3 * span, 0.0);
  if (k % 3 == 0)
  {
    otf->AddPoint(lo + (0.5 + 0.01 * (k % 7)) * span, 0.4, 0.3 + 0.05 * (k % 5), 0.2);
  }
  otf->AddPoint(hi, 0.3 + 0.7 * double(k % 37) / 36.0);
  ctf->RemoveAllPoints();
  ctf->AddRGBPoint(lo, 0.23, 0.30, 0.75);
  ctf->AddRGBPoint(lo + (0.4 + 0.2 * double(k % 11) / 10.0) * span, 0.87, 0.87, 0.87);
  ctf->AddRGBPoint(hi, 0.71, 0.02, 0.15);
  prop->SetScalarOpacityUnitDistance(0.05 + 0.02 * (k % 5));
}
}

int main(int argc, char* argv[])
{
  if (argc < 2)
  {
    std::fprintf(stderr, "usage: %s MODEL.inr [--changes N]\n", argv[0]);
    return 2;
  }
  int changes = 1000;
  int leakKiB = 0;
  for (int i = 2; i + 1 < argc; ++i)
  {
    if (std::string(argv[i]) == "--changes")
    {
      changes = std::max(200, std::atoi(argv[i + 1]));
    }
    else if (std::string(argv[i]) == "--leak-kib")
    {
      leakKiB = std::max(0, std::atoi(argv[i + 1]));
    }
  }
  const int warmup = 100;

  vtkNew<vtkInrVolumeReader> reader;
  reader->SetFileName(argv[1]);
  reader->SetPreviewResolution(2);
  reader->UpdateInformation();
  double timeRange[2], valueRange[2];
  reader->GetTimeRange(timeRange);
  reader->GetValueRange(valueRange);
  std::printf("model %s: time [%g, %g], values [%g, %g]\n", argv[1], timeRange[0], timeRange[1],
    valueRange[0], valueRange[1]);

  vtkNew<vtkInrVolumeMapper> mapper;
  mapper->SetInputConnection(reader->GetOutputPort());
  mapper->SetBackend(vtkInrVolumeMapper::BACKEND_CPU);
  mapper->SetMacrocellResolution(8);
  mapper->SetTemporalSlices(16);
  mapper->SetShadows(1);
  mapper->SetFramesPerRender(1);
  mapper->SetMaximumFrames(4);
  vtkNew<vtkVolume> volume;
  volume->SetMapper(mapper);
  vtkNew<vtkColorTransferFunction> ctf;
  vtkNew<vtkPiecewiseFunction> otf;
  volume->GetProperty()->SetColor(ctf);
  volume->GetProperty()->SetScalarOpacity(otf);
  editTransferFunction(volume->GetProperty(), ctf, otf, valueRange, 0);

  vtkNew<vtkRenderer> ren;
  ren->SetBackground(0.32, 0.34, 0.43);
  ren->AddVolume(volume);
  vtkNew<vtkRenderWindow> win;
  win->SetMultiSamples(0);
  win->SetSize(48, 32);
  win->AddRenderer(ren);
  reader->UpdateTimeStep(timeRange[0]);
  ren->ResetCamera();

  const auto t0 = std::chrono::steady_clock::now();
  double warmTime = 0, maxTime = 0, warmTf = 0, maxTf = 0;
  std::string curve;  // where growth happens, if it does (a step or a slope)
  int noFrame = 0;
  std::vector<std::vector<char>> held;  // the control's leak (--leak-kib)
  // After the warm-up, a step of more than 1 MiB between two samples names the mappings that grew.
  std::map<std::string, long> mappings;
  double lastSample = 0.0;
  auto sample = [&](int k, const char* phase)
  {
    const double now = residentMiB();
    if (k >= warmup && now - lastSample > 1.0)
    {
      std::map<std::string, long> next = residentByMapping();
      std::printf("step of %.2f MiB at %s change %d:\n", now - lastSample, phase, k);
      printGrowth(mappings, next);
      mappings.swap(next);
    }
    else if (k == warmup - 1)
    {
      mappings = residentByMapping();
    }
    lastSample = now;
    return now;
  };
  // 1000 time changes, cycling through 50 times over the range (every slice gets built early).
  for (int k = 0; k < changes; ++k)
  {
    const double t = timeRange[0] + (timeRange[1] - timeRange[0]) * double(k % 50) / 49.0;
    reader->UpdateTimeStep(t);
    win->Render();
    if (leakKiB > 0)
    {
      held.emplace_back(std::size_t(leakKiB) * 1024, char(k));  // resident, kept to the end
    }
    noFrame += mapper->GetAccumulatedFrames() < 1 ? 1 : 0;
    if (k == warmup - 1)
    {
      warmTime = sample(k, "time");
    }
    else if (k >= warmup && k % 10 == 0)
    {
      maxTime = std::max(maxTime, sample(k, "time"));
    }
    if ((k + 1) % 100 == 0)
    {
      curve += " " + std::to_string(int(residentMiB() * 10.0 + 0.5) / 10.0).substr(0, 5);
    }
  }
  std::printf("resident every 100 time changes (MiB):%s\n", curve.c_str());
  maxTime = std::max(maxTime, residentMiB());
  // 1000 transfer-function edits.
  for (int k = 0; k < changes; ++k)
  {
    editTransferFunction(volume->GetProperty(), ctf, otf, valueRange, k + 1);
    win->Render();
    noFrame += mapper->GetAccumulatedFrames() < 1 ? 1 : 0;
    if (k == warmup - 1)
    {
      warmTf = sample(warmup, "TF");  // (the mappings' snapshot stays the time changes')
    }
    else if (k >= warmup && k % 10 == 0)
    {
      maxTf = std::max(maxTf, sample(k, "TF"));
    }
  }
  maxTf = std::max(maxTf, residentMiB());
  const double seconds =
    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  std::printf("%d time changes + %d TF edits in %.1f s (%.1f ms per render)\n", changes, changes,
    seconds, 1000.0 * seconds / (2 * changes));
  std::printf("resident: %.1f MiB after %d time changes, max %.1f MiB after (growth %.2f MiB)\n",
    warmTime, warmup, maxTime, maxTime - warmTime);
  std::printf("resident: %.1f MiB after %d TF edits, max %.1f MiB after (growth %.2f MiB)\n",
    warmTf, warmup, maxTf, maxTf - warmTf);
  std::printf("engine builds %d, slices built %d, backend %s\n", mapper->GetEngineBuilds(),
    mapper->GetSlicesBuilt(), mapper->GetBackendInUse());
  check(maxTime - warmTime < kBoundMiB, "time changes: resident memory grows < 8 MiB after warm-up");
  check(maxTf - warmTf < kBoundMiB, "TF edits: resident memory grows < 8 MiB after warm-up");
  check(maxTf - warmTime < kBoundMiB, "whole run: resident memory grows < 8 MiB after warm-up");
  check(mapper->GetEngineBuilds() == 1, "time and TF changes keep the engine");
  check(mapper->GetSlicesBuilt() <= 16, "no slice built twice");
  check(noFrame == 0, "every render accumulated a frame");
  std::printf("%d failure(s)\n", failures);
  return failures == 0 ? 0 : 1;
}
