// Progress through VTK's events (issue 12, item 2), CPU backend, plain VTK render window:
//  - the reader's preview resampling reports ProgressEvents (several, non-decreasing, 0 -> 1) and
//    produces the same values in chunks as before;
//  - the mapper reports its macrocell builds from inside Render(): on a time change to slices not
//    built yet and after a macrocell-resolution change (engine rebuilt); several events,
//    non-decreasing, ending at 1, the progress text naming the build; nothing when no slice is
//    built;
//  - vtkInrVolumeRepresentation (the object ParaView's progress handler observes) re-issues the
//    mapper's events as its own, same values, with a short text ("INR macrocells") that fits
//    ParaView's progress bar.
// Usage: TestInrMapperProgress MODEL.inr
#include "InrPluginTestChecks.h"
#include "InrPluginTestScene.h"
#include "vtkColorTransferFunction.h"
#include "vtkCommand.h"
#include "vtkFloatArray.h"
#include "vtkImageData.h"
#include "vtkInrVolumeMapper.h"
#include "vtkInrVolumeReader.h"
#include "vtkInrVolumeRepresentation.h"
#include "vtkNew.h"
#include "vtkPiecewiseFunction.h"
#include "vtkPointData.h"
#include "vtkRenderWindow.h"
#include "vtkRenderer.h"
#include "vtkVolume.h"
#include "vtkVolumeProperty.h"

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

namespace
{
using inr_plugin_test::check;
using inr_plugin_test::failures;

// Records an algorithm's ProgressEvents whose progress text starts with `prefix` (the executive's
// own 0 / 1 around RequestData carry no such text, or an older one: those are filtered by the
// prefix only when the text was set by us).
struct ProgressRecorder
{
  std::string prefix;
  std::vector<double> values;
  std::vector<std::string> texts;

  void Observe(vtkAlgorithm* algorithm)
  {
    algorithm->AddObserver(vtkCommand::ProgressEvent, this, &ProgressRecorder::OnProgress);
  }
  void OnProgress(vtkObject* caller, unsigned long, void* data)
  {
    auto* algorithm = vtkAlgorithm::SafeDownCast(caller);
    const char* text = algorithm ? algorithm->GetProgressText() : nullptr;
    if (text && std::string(text).rfind(this->prefix, 0) == 0)
    {
      this->values.push_back(*static_cast<double*>(data));
      this->texts.push_back(text);
    }
  }
  void Clear()
  {
    this->values.clear();
    this->texts.clear();
  }
  std::string Describe() const
  {
    std::string s;
    for (double v : this->values)
    {
      char b[32];
      std::snprintf(b, sizeof(b), "%s%.3f", s.empty() ? "" : " ", v);
      s += b;
    }
    return "[" + s + "]" + (this->texts.empty() ? "" : " \"" + this->texts.back() + "\"");
  }
  // Several events, non-decreasing, from 0 to 1.
  void ExpectOneBuild(std::size_t minEvents, const std::string& what) const
  {
    const bool sorted = std::is_sorted(this->values.begin(), this->values.end());
    const bool ends = !this->values.empty() && this->values.front() == 0.0 && this->values.back() == 1.0;
    check(this->values.size() >= minEvents && sorted && ends,
      what + ": " + std::to_string(this->values.size()) + " events (>= " + std::to_string(minEvents) +
        "), non-decreasing, 0 -> 1: " + this->Describe());
  }
};

void setTransferFunction(vtkVolumeProperty* prop)
{
  vtkNew<vtkColorTransferFunction> ctf;
  vtkNew<vtkPiecewiseFunction> otf;
  SetTestRamps(ctf, otf);
  prop->SetColor(ctf);
  prop->SetScalarOpacity(otf);
  prop->SetScalarOpacityUnitDistance(0.1);
}
}

int main(int argc, char* argv[])
{
  if (argc < 2)
  {
    std::fprintf(stderr, "usage: %s MODEL.inr\n", argv[0]);
    return 2;
  }

  // --- The reader's preview: 64^3 points, reported in chunks.
  {
    vtkNew<vtkInrVolumeReader> reader;
    reader->SetFileName(argv[1]);
    reader->SetPreviewResolution(64);
    ProgressRecorder rec{ "INR Volume reader" };
    rec.Observe(reader);
    reader->UpdateTimeStep(2.5);
    rec.ExpectOneBuild(4, "reader: preview resampling at 64^3");
    check(!rec.texts.empty() && rec.texts.back() == "INR Volume reader: sampling the preview grid",
      "reader: progress text says what it does");
    // The chunked evaluation gives the values of one evaluation at full resolution: compare the
    // corner points with a 2^3 preview (the same world points) at the same time.
    vtkNew<vtkInrVolumeReader> corners;
    corners->SetFileName(argv[1]);
    corners->SetPreviewResolution(2);
    corners->UpdateTimeStep(2.5);
    auto* big = vtkFloatArray::SafeDownCast(reader->GetOutput()->GetPointData()->GetArray("value"));
    // The 8 box corners of an r^3 preview equal those of the 64^3 one, bit for bit.
    auto sameCorners = [big](vtkInrVolumeReader* other, int r) {
      auto* v = vtkFloatArray::SafeDownCast(other->GetOutput()->GetPointData()->GetArray("value"));
      bool same = big && v && big->GetNumberOfTuples() == 64 * 64 * 64 &&
        v->GetNumberOfTuples() == vtkIdType(r) * r * r;
      for (int c = 0; same && c < 8; ++c)
      {
        auto at = [c](int n, int bit) { return (c & bit) ? n - 1 : 0; };
        same = big->GetValue(at(64, 1) + 64 * (at(64, 2) + 64 * at(64, 4))) ==
          v->GetValue(at(r, 1) + r * (at(r, 2) + r * at(r, 4)));
      }
      return same;
    };
    check(sameCorners(corners, 2), "reader: chunked preview values equal the corners of an unchunked one");
    // The default 8^3 preview is evaluated in chunks small enough to use every core: the same
    // values again.
    vtkNew<vtkInrVolumeReader> preview;
    preview->SetFileName(argv[1]);
    preview->UpdateTimeStep(2.5);
    check(sameCorners(preview, 8), "reader: the default preview, in small chunks over every core, gives the same values");
  }

  // --- The mapper, inside the representation ParaView would create.
  vtkNew<vtkInrVolumeReader> reader;
  reader->SetFileName(argv[1]);
  reader->SetPreviewResolution(2);
  vtkNew<vtkInrVolumeRepresentation> representation;
  vtkInrVolumeMapper* mapper = representation->GetInrMapper();
  mapper->SetInputConnection(reader->GetOutputPort());
  mapper->SetBackend(vtkInrVolumeMapper::BACKEND_CPU);
  mapper->SetMacrocellResolution(32);  // 512 tiles: two lattice batches per slice
  mapper->SetTemporalSlices(16);
  mapper->SetFramesPerRender(1);
  mapper->SetMaximumFrames(2);
  mapper->SetRefinementTimeBudget(0.0);  // one frame per render: the checks count them
  vtkNew<vtkVolume> volume;
  volume->SetMapper(mapper);
  setTransferFunction(volume->GetProperty());
  vtkNew<vtkRenderer> ren;
  ren->AddVolume(volume);
  vtkNew<vtkRenderWindow> win;
  win->SetMultiSamples(0);
  win->SetSize(48, 32);
  win->AddRenderer(ren);

  ProgressRecorder fromMapper{ "INR Volume: building macrocells" };
  ProgressRecorder fromRepresentation{ "INR macrocells" };
  fromMapper.Observe(mapper);
  fromRepresentation.Observe(representation);

  reader->UpdateTimeStep(2.5);
  ren->ResetCamera();
  win->Render();
  fromMapper.ExpectOneBuild(3, "mapper: first render (engine created, slices of t = 2.5)");
  check(mapper->GetAccumulatedFrames() == 1, "mapper: the first render shows a frame");

  fromMapper.Clear();
  fromRepresentation.Clear();
  const int slicesBefore = mapper->GetSlicesBuilt();
  reader->UpdateTimeStep(7.1);  // between slices 10 and 11: neither built yet
  win->Render();
  fromMapper.ExpectOneBuild(5, "mapper: time change to unbuilt slices");
  check(mapper->GetSlicesBuilt() == slicesBefore + 2,
    "mapper: the time change built two slices (" + std::to_string(slicesBefore) + " -> " +
      std::to_string(mapper->GetSlicesBuilt()) + ")");
  check(!fromMapper.texts.empty() &&
      fromMapper.texts.back() == "INR Volume: building macrocells: 2 of 16 time slices, 32x32x32 cells",
    "mapper: progress text names the build");
  check(fromRepresentation.values == fromMapper.values &&
      std::all_of(fromRepresentation.texts.begin(), fromRepresentation.texts.end(),
        [](const std::string& t) { return t == "INR macrocells"; }),
    "representation: re-issues the mapper's events with a short text for the progress bar (" +
      fromRepresentation.Describe() + ")");

  fromMapper.Clear();
  reader->UpdateTimeStep(7.3);  // the same two slices: nothing to build
  win->Render();
  check(fromMapper.values.empty(), "mapper: no progress when no slice is built " + fromMapper.Describe());

  fromMapper.Clear();
  fromRepresentation.Clear();
  const int buildsBefore = mapper->GetEngineBuilds();
  mapper->SetMacrocellResolution(64);  // 4096 tiles: 12 lattice batches per slice
  win->Render();
  check(mapper->GetEngineBuilds() == buildsBefore + 1, "mapper: a resolution change rebuilds the engine");
  fromMapper.ExpectOneBuild(12, "mapper: macrocell-resolution change");
  check(fromRepresentation.values == fromMapper.values,
    "representation: re-issues the rebuild's events too");

  std::printf("%d failure(s)\n", failures);
  return failures == 0 ? 0 : 1;
}
