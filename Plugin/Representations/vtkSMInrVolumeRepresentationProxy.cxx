#include "vtkSMInrVolumeRepresentationProxy.h"

#include "vtkObjectFactory.h"
#include "vtkPVSession.h"
#include "vtkSMSessionClient.h"

vtkStandardNewMacro(vtkSMInrVolumeRepresentationProxy);

vtkSMInrVolumeRepresentationProxy::vtkSMInrVolumeRepresentationProxy() = default;
vtkSMInrVolumeRepresentationProxy::~vtkSMInrVolumeRepresentationProxy() = default;

void vtkSMInrVolumeRepresentationProxy::UpdatePropertyInformationInternal(vtkSMProperty* prop)
{
  // A remote session (a client connected to pvserver, or to separate data and render servers)
  // with the representation on its render server: the pull goes there. The superclass builds the
  // pull request and loads the answer; it addresses the request to this->Location, so the
  // location is narrowed for that one call. Builtin sessions and server-side proxies pull from
  // the process itself, as before.
  const vtkTypeUInt32 location = this->Location;
  const bool remote = vtkSMSessionClient::SafeDownCast(this->GetSession()) != nullptr;
  if (!remote || (location & vtkPVSession::RENDER_SERVER) == 0)
  {
    this->Superclass::UpdatePropertyInformationInternal(prop);
    return;
  }
  this->Location = vtkPVSession::RENDER_SERVER_ROOT;
  this->Superclass::UpdatePropertyInformationInternal(prop);
  this->Location = location;
}

void vtkSMInrVolumeRepresentationProxy::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
}
