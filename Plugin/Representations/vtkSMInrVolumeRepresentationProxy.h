/**
 * @class vtkSMInrVolumeRepresentationProxy
 * @brief The server-manager proxy of the INR Volume representation: its information properties
 * come from the process that renders.
 *
 * The panel's information properties (frames accumulated, converged, the refinement state, the
 * ranks and the backend in use) describe the representation that renders. A representation
 * exists on the client and on the servers, and ParaView pulls information properties from the
 * client's copy when there is one (vtkSMSessionClient::PullState: the client first), which in
 * client/server mode does not render: its frame count stays 0. In a remote session this proxy
 * pulls them from the render server's root instead (the same object a builtin session reads).
 * Named in ServerManagerXML/InrVolumeRepresentation.xml (<InrVolumeRepresentationProxy>).
 */
#ifndef vtkSMInrVolumeRepresentationProxy_h
#define vtkSMInrVolumeRepresentationProxy_h

#include "InrVolumeRepresentationsModule.h"
#include "vtkSMRepresentationProxy.h"

class INRVOLUMEREPRESENTATIONS_EXPORT vtkSMInrVolumeRepresentationProxy : public vtkSMRepresentationProxy
{
public:
  static vtkSMInrVolumeRepresentationProxy* New();
  vtkTypeMacro(vtkSMInrVolumeRepresentationProxy, vtkSMRepresentationProxy);
  void PrintSelf(ostream& os, vtkIndent indent) override;

protected:
  vtkSMInrVolumeRepresentationProxy();
  ~vtkSMInrVolumeRepresentationProxy() override;

  void UpdatePropertyInformationInternal(vtkSMProperty* prop = nullptr) override;

private:
  vtkSMInrVolumeRepresentationProxy(const vtkSMInrVolumeRepresentationProxy&) = delete;
  void operator=(const vtkSMInrVolumeRepresentationProxy&) = delete;
};

#endif
