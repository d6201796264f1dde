/**
 * @class vtkInrVolumeReader
 * @brief Reads an INR Volume model (.inr: safetensors weights + JSON architecture/domain) as a
 * continuous, time-dependent source.
 *
 * Output: a vtkImageData covering the model's world box with `PreviewResolution`^3 node-centred
 * samples of the field at the requested time (point array "value"), for ParaView's other filters
 * (slices, contours). The volume mapper never uses these samples: it evaluates the network itself.
 * Field data carries the model downstream, so it also reaches a remote render server:
 *  - "InrModel":      vtkUnsignedCharArray, the file's raw bytes (rebuilt with InrModel::loadBytes)
 *  - "InrValueRange": vtkDoubleArray, 2 tuples: the model's value range (hint or sampled)
 *  - "InrTime":       vtkDoubleArray, 1 tuple: the world time of this output
 * Information: a continuous TIME_RANGE (no TIME_STEPS, so time moves continuously); static models
 * report no time at all. Errors (unreadable or malformed file) are reported with vtkErrorMacro and
 * the loader's message; the request fails, nothing crashes. A file that changes on disk after it
 * was read is read again (Reload, GetMTime); if its new content is bad or it is deleted, the model
 * read before stays, with a warning.
 *
 * In parallel (several pieces), piece 0 carries the whole model and preview; other pieces are
 * empty, so the volume is rendered exactly once.
 */
#ifndef vtkInrVolumeReader_h
#define vtkInrVolumeReader_h

#include "InrVolumeReadersModule.h"
#include "vtkImageAlgorithm.h"

#include <string>  // for TransferFunctionJSON

class INRVOLUMEREADERS_EXPORT vtkInrVolumeReader : public vtkImageAlgorithm
{
public:
  static vtkInrVolumeReader* New();
  vtkTypeMacro(vtkInrVolumeReader, vtkImageAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  ///@{
  /// The model file.
  virtual void SetFileName(const char* name);
  vtkGetStringMacro(FileName);
  ///@}

  ///@{
  /// Samples per axis of the preview grid (2..256, default 8). 2 = only the box corners
  /// (effectively off); raise it to slice or contour the model with other filters.
  vtkSetClampMacro(PreviewResolution, int, 2, 256);
  vtkGetMacro(PreviewResolution, int);
  ///@}

  ///@{
  /// Where the preview grid is evaluated: 0 = Auto (the GPU where a usable one is, else the
  /// CPU), 1 = CPU, 2 = CUDA (without a usable GPU: a warning naming why, and the CPU).
  /// PreviewBackendInUse says which one the last preview ran on ("" before the first), and why
  /// not the GPU.
  vtkSetClampMacro(PreviewBackend, int, 0, 2);
  vtkGetMacro(PreviewBackend, int);
  const char* GetPreviewBackendInUse() { return this->PreviewBackendInUse.c_str(); }
  ///@}

  // No CanReadFile on purpose: ParaView picks this reader by the .inr extension, and a broken
  // file then gets the loader's precise message instead of "no reader found".

  ///@{
  /// Filled by RequestInformation: the model's time range and value range.
  vtkGetVector2Macro(TimeRange, double);
  vtkGetVector2Macro(ValueRange, double);
  ///@}

  /// The model's own colour and opacity map: the text of the ParaView preset file beside the
  /// model (MODEL.tf.json for MODEL.inr: a JSON list holding one preset with RGBPoints and
  /// Points, as Tools/ ships them), "" when there is none. A file that is there but broken (not
  /// JSON, no RGBPoints, wrong groups, non-finite values, opacity outside [0, 1], unreadable,
  /// empty) gives "" too, with a warning naming the file and the problem (once per state of the
  /// file), so the default colour map is used. ParaView's GUI applies the text when the model is
  /// first shown as INR Volume.
  const char* GetTransferFunctionJSON();

  /// Reads the model file again at the next update, even if it looks unchanged (ParaView's
  /// File > Reload Files, through the proxy's ReloadFiles hint). A change on disk (size,
  /// modification time, inode) is noticed without it at the next pipeline update. When the new
  /// content does not load (truncated, malformed, caught half-written) or the file is gone, the
  /// model read before is kept and shown, with one warning naming the file and the problem.
  void Reload();

  /// The superclass's MTime, or later when the model file changed on disk since it was read.
  vtkMTimeType GetMTime() override;

protected:
  vtkInrVolumeReader();
  ~vtkInrVolumeReader() override;

  int RequestInformation(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;
  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;

private:
  vtkInrVolumeReader(const vtkInrVolumeReader&) = delete;
  void operator=(const vtkInrVolumeReader&) = delete;
  bool LoadModel();
  void WarnOnce(const std::string& problem, const std::string& key);

  char* FileName = nullptr;
  int PreviewResolution = 8;
  int PreviewBackend = 0;
  std::string PreviewBackendInUse;
  double TimeRange[2] = { 0, 0 };
  double ValueRange[2] = { 0, 1 };
  std::string TransferFunctionJSON;
  std::string WarnedTransferFunction;  // the problem and file state last warned about
  struct Internals;
  Internals* Internal;
};

#endif
