#include "vtkInrVolumeReader.h"

#include "vtkDoubleArray.h"
#include "vtkFieldData.h"
#include "vtkFloatArray.h"
#include "vtkImageData.h"
#include "vtkInformation.h"
#include "vtkInformationDoubleVectorKey.h"
#include "vtkInformationInformationVectorKey.h"
#include "vtkInformationVector.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkPointData.h"
#include "vtkSmartPointer.h"
#include "vtkStreamingDemandDrivenPipeline.h"
#include "vtkTimeStamp.h"
#include "vtkUnsignedCharArray.h"

#include "Backends/PreviewEvaluator.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Evaluator/ValueRange.h"
#include "Model/InrModel.h"
#include "Render/SceneInputs.h"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <memory>
#include <sys/stat.h>
#include <vector>

// What identifies one version of the model file on disk: a rewrite in place changes the size or
// the modification time (nanoseconds where the file system keeps them), a replacement by rename
// (an atomic save) the inode. `exists` false: the file is gone.
struct ModelFileState
{
  bool exists = false;
  long long size = -1;
  long long mtimeSec = 0;
  long long mtimeNsec = 0;
  unsigned long long inode = 0;
  unsigned long long device = 0;

  static ModelFileState Of(const char* path)
  {
    ModelFileState s;
    struct stat st;
    if (path && ::stat(path, &st) == 0)
    {
      s.exists = true;
      s.size = static_cast<long long>(st.st_size);
      s.mtimeSec = static_cast<long long>(st.st_mtim.tv_sec);
      s.mtimeNsec = static_cast<long long>(st.st_mtim.tv_nsec);
      s.inode = static_cast<unsigned long long>(st.st_ino);
      s.device = static_cast<unsigned long long>(st.st_dev);
    }
    return s;
  }
  bool operator==(const ModelFileState& o) const
  {
    return exists == o.exists && size == o.size && mtimeSec == o.mtimeSec &&
      mtimeNsec == o.mtimeNsec && inode == o.inode && device == o.device;
  }
  bool operator!=(const ModelFileState& o) const { return !(*this == o); }
};

struct vtkInrVolumeReader::Internals
{
  std::string loadedPath;  // the file `seen` belongs to
  ModelFileState seen;     // the state of the file last read (or found missing)
  ModelFileState noticed;  // a change GetMTime has already announced
  bool ok = false;         // a model read from loadedPath is held (maybe from an earlier version)
  bool reloadAsked = false;  // Reload(): read the file again even if it looks unchanged
  std::string warnedFileProblem;  // the problem and file state last warned about
  vtkTimeStamp fileChanged;       // when GetMTime noticed the file change on disk
  inr::InrModel model;
  // The preview's evaluator (the GPU's where there is one, PreviewBackend), made for `model`.
  std::unique_ptr<inr::PreviewEvaluator> previewEvaluator;
  int previewBackend = -1;  // the PreviewBackend it was made for
  vtkSmartPointer<vtkUnsignedCharArray> bytes;  // shared by every output (same pointer over time)
};

namespace
{
// ParaView's data information (on Apply, in the GUI's event loop) takes the range and the finite
// range of every array, the model's bytes included, with VTK's generic scan: tens of ms for the
// paper-size models (RESULTS.md, "Apply: the plugin's part of the event-loop stall"), where
// std::minmax_element over the bytes takes a fraction of a millisecond. The range is stored where
// vtkDataArray caches its ranges (per component, valid while the array is not modified after
// it), so the scan finds it. Were VTK's cache to change, the scan simply runs.
void CacheByteRange(vtkUnsignedCharArray* array)
{
  const vtkIdType n = array->GetNumberOfValues();
  if (n == 0 || array->GetNumberOfComponents() != 1)
  {
    return;
  }
  const unsigned char* bytes = array->GetPointer(0);
  const auto [lo, hi] = std::minmax_element(bytes, bytes + n);
  const double range[2] = { double(*lo), double(*hi) };
  for (vtkInformationInformationVectorKey* perComponent :
    { vtkDataArray::PER_COMPONENT(), vtkDataArray::PER_FINITE_COMPONENT() })
  {
    vtkNew<vtkInformationVector> components;
    components->SetNumberOfInformationObjects(1);
    components->GetInformationObject(0)->Set(vtkDataArray::COMPONENT_RANGE(), range, 2);
    array->GetInformation()->Set(perComponent, components);
  }
}
} // namespace

vtkStandardNewMacro(vtkInrVolumeReader);

vtkInrVolumeReader::vtkInrVolumeReader()
  : Internal(new Internals)
{
  this->SetNumberOfInputPorts(0);
}

vtkInrVolumeReader::~vtkInrVolumeReader()
{
  this->SetFileName(nullptr);
  delete this->Internal;
}

const char* vtkInrVolumeReader::GetTransferFunctionJSON()
{
  this->TransferFunctionJSON.clear();
  std::string path = this->FileName ? this->FileName : "";
  const std::string ext = ".inr";
  if (path.size() <= ext.size() || path.compare(path.size() - ext.size(), ext.size(), ext) != 0)
  {
    return this->TransferFunctionJSON.c_str();
  }
  path = path.substr(0, path.size() - ext.size()) + ".tf.json";
  struct stat st;
  if (::stat(path.c_str(), &st) != 0)
  {
    return this->TransferFunctionJSON.c_str();  // no colour map beside the model: the default
  }
  // What is wrong with the file, "" when nothing is. The same checks as `inr render --tf`
  // (the engine's parser and table), so a map ParaView would be handed is one the engine reads.
  std::string problem;
  std::string text;
  constexpr long long kMaxBytes = 1 << 20;  // a preset is a few hundred bytes
  const long long size = static_cast<long long>(st.st_size);
  if (size == 0)
  {
    problem = path + ": the file is empty";
  }
  else if (size > kMaxBytes)
  {
    problem = path + ": " + std::to_string(size) + " bytes, more than a colour map preset holds (at most " +
      std::to_string(kMaxBytes) + ")";
  }
  else
  {
    std::ifstream in(path, std::ios::binary);
    text.resize(std::size_t(size));
    if (!in || !in.read(&text[0], size))
    {
      problem = path + ": cannot read the file";
    }
    else
    {
      try
      {
        const inr::TransferFunction tf = inr::TransferFunction::fromParaViewJson(text, path);
        inr::TransferFunctionTable table(tf);  // non-finite or misordered points
      }
      catch (const std::exception& e)
      {
        problem = e.what();
        if (problem.compare(0, path.size(), path) != 0)
        {
          problem = path + ": " + problem;
        }
        // Python's json module writes non-finite floats as these literals, which JSON lacks.
        if (text.find("NaN") != std::string::npos || text.find("Infinity") != std::string::npos)
        {
          problem += " (it holds NaN or Infinity: a non-finite value, which a colour map cannot use)";
        }
      }
    }
  }
  if (problem.empty())
  {
    this->TransferFunctionJSON = text;
    this->WarnedTransferFunction.clear();
    return this->TransferFunctionJSON.c_str();
  }
  // Once per state of the file: ParaView asks for this property more than once per model.
  const std::string warned = problem + "|" + std::to_string(static_cast<long long>(st.st_mtime)) +
    "|" + std::to_string(size);
  if (warned != this->WarnedTransferFunction)
  {
    this->WarnedTransferFunction = warned;
    vtkWarningMacro(<< "the model's colour map " << problem
                    << "; the default colour map is used instead");
  }
  return this->TransferFunctionJSON.c_str();
}

void vtkInrVolumeReader::SetFileName(const char* name)
{
  if (name && this->FileName && std::strcmp(name, this->FileName) == 0)
  {
    return;
  }
  delete[] this->FileName;
  this->FileName = nullptr;
  if (name)
  {
    this->FileName = new char[std::strlen(name) + 1];
    std::strcpy(this->FileName, name);
  }
  this->Modified();
}

void vtkInrVolumeReader::Reload()
{
  this->Internal->reloadAsked = true;
  this->Modified();
}

vtkMTimeType vtkInrVolumeReader::GetMTime()
{
  // A model file rewritten or deleted on disk (a training script saving a checkpoint) makes the
  // reader out of date, so the next pipeline update (a time step, UpdatePipeline) reads it again
  // without File > Reload Files. One stat per call; each new state of the file is announced once.
  Internals& I = *this->Internal;
  if (this->FileName && I.loadedPath == this->FileName)
  {
    const ModelFileState now = ModelFileState::Of(this->FileName);
    if (now != I.seen && now != I.noticed)
    {
      I.noticed = now;
      I.fileChanged.Modified();
    }
  }
  return std::max(this->Superclass::GetMTime(), I.fileChanged.GetMTime());
}

void vtkInrVolumeReader::WarnOnce(const std::string& problem, const std::string& key)
{
  if (key == this->Internal->warnedFileProblem)
  {
    return;
  }
  this->Internal->warnedFileProblem = key;
  vtkWarningMacro(<< problem);
}

bool vtkInrVolumeReader::LoadModel()
{
  Internals& I = *this->Internal;
  const bool reloadAsked = I.reloadAsked;
  I.reloadAsked = false;
  if (!this->FileName || !*this->FileName)
  {
    vtkErrorMacro("No FileName set: give the INR Volume model (.inr) to read.");
    I.ok = false;
    return false;
  }
  const std::string path = this->FileName;
  // A model already read from this file is kept when the file goes away or its new content does
  // not load: the view goes on showing it, and the user is told once per state of the file.
  const bool holdsModel = I.ok && I.loadedPath == path;
  const ModelFileState before = ModelFileState::Of(this->FileName);
  if (!before.exists)
  {
    if (holdsModel)
    {
      I.seen = before;
      this->WarnOnce(path + ": the model file is gone (deleted, moved or renamed); the model "
          "read from it before is still shown. Put the file back and use File > Reload Files "
          "(pvpython: ReloadFiles) to read it again.",
        path + "|gone");
      return true;
    }
    vtkErrorMacro(<< path << ": cannot open the file (does it exist?)");
    I.ok = false;
    I.loadedPath.clear();
    return false;
  }
  if (I.loadedPath == path && I.seen == before && !reloadAsked)
  {
    return I.ok;  // unchanged (also remembers a failure, so it is reported once per change)
  }
  const bool hadFailed = I.loadedPath == path && !I.ok;
  I.loadedPath = path;
  I.seen = before;
  I.noticed = before;
  // Everything is read and checked into these before any of it replaces the held model: a file
  // caught half-written (a save in progress) fails to parse and leaves the model as it was.
  inr::InrModel model;
  double valueRange[2] = { 0, 1 };
  vtkSmartPointer<vtkUnsignedCharArray> bytes;
  std::string problem;
  try
  {
    std::ifstream in(this->FileName, std::ios::binary);
    std::vector<char> data(static_cast<std::size_t>(before.size));
    if (!in || !in.read(data.data(), before.size))
    {
      throw inr::ModelError(path + ": cannot read the file");
    }
    model = inr::InrModel::loadBytes(
      reinterpret_cast<const std::uint8_t*>(data.data()), data.size(), this->FileName);
    model.path = path;
    const auto vr = inr::valueRangeFor(model, inr::CpuInrEvaluator(model));
    valueRange[0] = vr[0];
    valueRange[1] = vr[1];
    bytes = vtkSmartPointer<vtkUnsignedCharArray>::New();
    bytes->SetName("InrModel");
    bytes->SetNumberOfTuples(static_cast<vtkIdType>(data.size()));
    std::memcpy(bytes->GetPointer(0), data.data(), data.size());
    CacheByteRange(bytes);
  }
  catch (const std::exception& e)
  {
    problem = e.what();
  }
  // A file that changed while it was read may hold parts of two versions even where they parse:
  // it is not taken, and is read again at the next update (GetMTime sees the state differ from
  // `seen`).
  if (ModelFileState::Of(this->FileName) != before)
  {
    problem = problem.empty() ? path + ": the file changed while it was read (a save still in progress?)"
                              : problem + " (the file changed while it was read: a save still in progress?)";
  }
  if (!problem.empty())
  {
    if (holdsModel)
    {
      // The loader's messages start with the file name already.
      const std::string what =
        problem.compare(0, path.size(), path) == 0 ? problem : path + ": " + problem;
      this->WarnOnce("the model file changed on disk but its new content cannot be read: " +
          what + ". The model read before is still shown; it is read again when the file " +
          "changes (or with File > Reload Files).",
        path + "|" + problem + "|" + std::to_string(before.size) + "|" +
          std::to_string(before.mtimeSec) + "." + std::to_string(before.mtimeNsec));
      return true;
    }
    I.ok = false;
    I.previewEvaluator.reset();
    I.bytes = nullptr;
    vtkErrorMacro(<< problem);
    return false;
  }
  if (holdsModel || hadFailed)
  {
    this->Internal->warnedFileProblem.clear();  // a later fault of the file is news again
  }
  I.previewEvaluator.reset();  // it refers to the model it was made for
  I.model = std::move(model);
  I.bytes = bytes;  // a new array: the mapper sees new bytes and restarts its accumulation
  this->ValueRange[0] = valueRange[0];
  this->ValueRange[1] = valueRange[1];
  this->TimeRange[0] = I.model.domain.timeBegin;
  this->TimeRange[1] = I.model.domain.timeEnd;
  I.ok = true;
  return true;
}

int vtkInrVolumeReader::RequestInformation(
  vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  if (!this->LoadModel())
  {
    return 0;
  }
  const inr::Domain& d = this->Internal->model.domain;
  vtkInformation* outInfo = outputVector->GetInformationObject(0);
  const int r = this->PreviewResolution;
  int extent[6] = { 0, r - 1, 0, r - 1, 0, r - 1 };
  double origin[3] = { d.bounds[0], d.bounds[2], d.bounds[4] };
  double spacing[3];
  for (int a = 0; a < 3; ++a)
  {
    spacing[a] = (d.bounds[2 * a + 1] - d.bounds[2 * a]) / (r - 1);
  }
  outInfo->Set(vtkStreamingDemandDrivenPipeline::WHOLE_EXTENT(), extent, 6);
  outInfo->Set(vtkDataObject::ORIGIN(), origin, 3);
  outInfo->Set(vtkDataObject::SPACING(), spacing, 3);
  vtkDataObject::SetPointDataActiveScalarInfo(outInfo, VTK_FLOAT, 1);
  // Every piece executes (the model travels with each: sub-domain rendering under MPI); without
  // this the executive hands ranks > 0 an empty image without running the reader.
  outInfo->Set(vtkAlgorithm::CAN_HANDLE_PIECE_REQUEST(), 1);
  outInfo->Remove(vtkStreamingDemandDrivenPipeline::TIME_STEPS());
  if (d.usesTime() && d.timeEnd > d.timeBegin)
  {
    // Continuous time: a range and no steps, so the time slider and animations move freely.
    outInfo->Set(vtkStreamingDemandDrivenPipeline::TIME_RANGE(), this->TimeRange, 2);
  }
  else
  {
    outInfo->Remove(vtkStreamingDemandDrivenPipeline::TIME_RANGE());
  }
  return 1;
}

int vtkInrVolumeReader::RequestData(
  vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  vtkInformation* outInfo = outputVector->GetInformationObject(0);
  vtkImageData* output = vtkImageData::GetData(outInfo);
  if (!output || !this->LoadModel())
  {
    return 0;
  }
  Internals& I = *this->Internal;
  const inr::Domain& d = I.model.domain;

  double t = d.timeBegin;
  if (outInfo->Has(vtkStreamingDemandDrivenPipeline::UPDATE_TIME_STEP()))
  {
    t = outInfo->Get(vtkStreamingDemandDrivenPipeline::UPDATE_TIME_STEP());
  }
  t = std::min(std::max(t, d.timeBegin), d.timeEnd);
  if (!d.usesTime())
  {
    t = 0.5 * (d.timeBegin + d.timeEnd);
  }

  const int piece = outInfo->Has(vtkStreamingDemandDrivenPipeline::UPDATE_PIECE_NUMBER())
    ? outInfo->Get(vtkStreamingDemandDrivenPipeline::UPDATE_PIECE_NUMBER())
    : 0;
  const int r = this->PreviewResolution;
  output->SetOrigin(d.bounds[0], d.bounds[2], d.bounds[4]);
  output->SetSpacing((d.bounds[1] - d.bounds[0]) / (r - 1), (d.bounds[3] - d.bounds[2]) / (r - 1),
    (d.bounds[5] - d.bounds[4]) / (r - 1));
  // The model (a few MB at most) travels with every piece: under MPI each rank renders its own
  // brick of it with the whole network (sub-domain rendering, vtkInrVolumeMapper). The preview
  // grid, data for other filters, lives on piece 0 only.
  auto addModelArrays = [&](vtkFieldData* fd) {
    fd->AddArray(I.bytes);
    vtkNew<vtkDoubleArray> range;
    range->SetName("InrValueRange");
    range->SetNumberOfTuples(2);
    range->SetValue(0, this->ValueRange[0]);
    range->SetValue(1, this->ValueRange[1]);
    fd->AddArray(range);
    vtkNew<vtkDoubleArray> time;
    time->SetName("InrTime");
    time->SetNumberOfTuples(1);
    time->SetValue(0, t);
    fd->AddArray(time);
    vtkNew<vtkDoubleArray> bounds;  // the model's box, for the ranks' brick bounds
    bounds->SetName("InrDomainBounds");
    bounds->SetNumberOfTuples(6);
    for (int k = 0; k < 6; ++k)
    {
      bounds->SetValue(k, d.bounds[k]);
    }
    fd->AddArray(bounds);
  };
  if (piece > 0)
  {
    output->SetExtent(0, -1, 0, -1, 0, -1);
    // An empty "value" array as the active scalars: ParaView's volume prop draws a volume only
    // when its input has scalars (vtkPVLODVolume::CanRender), and each rank draws its share.
    vtkNew<vtkFloatArray> none;
    none->SetName("value");
    output->GetPointData()->SetScalars(none);
    addModelArrays(output->GetFieldData());
    output->GetInformation()->Set(vtkDataObject::DATA_TIME_STEP(), t);
    return 1;
  }
  output->SetExtent(0, r - 1, 0, r - 1, 0, r - 1);

  const std::size_t n = static_cast<std::size_t>(r) * r * r;
  std::vector<inr::QueryPoint> pts(n);
  std::size_t k = 0;
  for (int z = 0; z < r; ++z)
  {
    for (int y = 0; y < r; ++y)
    {
      for (int x = 0; x < r; ++x, ++k)
      {
        double p[3];
        output->GetPoint(static_cast<vtkIdType>(k), p);
        pts[k] = inr::QueryPoint{ float(p[0]), float(p[1]), float(p[2]), float(t) };
      }
    }
  }
  vtkNew<vtkFloatArray> values;
  values->SetName("value");
  values->SetNumberOfTuples(static_cast<vtkIdType>(n));
  // Evaluated in chunks so that a large preview reports progress (ParaView's progress bar) and can
  // be aborted between chunks; the chunks give the values of one call over every point.
  if (!I.previewEvaluator || I.previewBackend != this->PreviewBackend)
  {
    inr::PreviewEvaluatorOptions options;
    options.backend = this->PreviewBackend == 1 ? inr::RenderBackend::Cpu
      : this->PreviewBackend == 2                ? inr::RenderBackend::Cuda
                                                 : inr::RenderBackend::Auto;
    std::string refused;
    try
    {
      I.previewEvaluator = std::make_unique<inr::PreviewEvaluator>(I.model, options);
    }
    catch (const std::exception& e)
    {
      // CUDA asked for and not there: the preview still comes (on the CPU), and so does the
      // model for the INR Volume representation downstream; the warning says why.
      refused = e.what();
      vtkWarningMacro(<< I.loadedPath << ": Preview Backend CUDA: " << refused
                      << "; the preview grid is evaluated on the CPU (Preview Backend Auto or CPU says so "
                         "without this warning)");
      options.backend = inr::RenderBackend::Cpu;
      I.previewEvaluator = std::make_unique<inr::PreviewEvaluator>(I.model, options);
    }
    I.previewBackend = this->PreviewBackend;
    this->PreviewBackendInUse = refused.empty() ? I.previewEvaluator->description() : "CPU (" + refused + ")";
  }
  const std::size_t chunk = I.previewEvaluator->chunkPoints(n);
  this->SetProgressText("INR Volume reader: sampling the preview grid");
  this->UpdateProgress(0.0);
  try
  {
    for (std::size_t first = 0; first < n; first += chunk)
    {
      if (this->GetAbortExecute())
      {
        output->Initialize();  // no half-filled preview downstream
        return 1;
      }
      const std::size_t count = std::min(chunk, n - first);
      I.previewEvaluator->evaluate(pts.data() + first, count, values->GetPointer(0) + first);
      this->UpdateProgress(static_cast<double>(first + count) / static_cast<double>(n));
    }
    this->SetProgressText(nullptr);  // the executive's own events are not the sampling's
  }
  catch (const std::exception& e)
  {
    vtkErrorMacro(<< I.loadedPath << ": evaluation failed: " << e.what());
    return 0;
  }
  output->GetPointData()->SetScalars(values);

  addModelArrays(output->GetFieldData());
  output->GetInformation()->Set(vtkDataObject::DATA_TIME_STEP(), t);
  return 1;
}

void vtkInrVolumeReader::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "FileName: " << (this->FileName ? this->FileName : "(none)") << "\n";
  os << indent << "PreviewResolution: " << this->PreviewResolution << "\n";
  os << indent << "PreviewBackend: " << this->PreviewBackend << " (in use: " << this->PreviewBackendInUse
     << ")\n";
  os << indent << "TimeRange: " << this->TimeRange[0] << " " << this->TimeRange[1] << "\n";
  os << indent << "ValueRange: " << this->ValueRange[0] << " " << this->ValueRange[1] << "\n";
}
