#include "pqInrPanelDecorators.h"

#include "pqPropertyWidget.h"
#include "vtkCommand.h"
#include "vtkSMProperty.h"
#include "vtkSMPropertyHelper.h"
#include "vtkSMProxy.h"

#include <cstring>

namespace
{
// The sub-proxy of INR Volume's own properties (ServerManagerXML/InrVolumeRepresentation.xml).
constexpr const char* kInrSubProxy = "InrVolumeRepresentation";

bool showsInrVolume(vtkSMProxy* representation)
{
  vtkSMProperty* type = representation ? representation->GetProperty("Representation") : nullptr;
  const char* value = type ? vtkSMPropertyHelper(type).GetAsString() : nullptr;
  return value && std::strcmp(value, "INR Volume") == 0;
}
}

pqInrPanelDecorators::pqInrPanelDecorators(QObject* parent)
  : QObject(parent)
{
}

pqInrPanelDecorators::~pqInrPanelDecorators() = default;

bool pqInrPanelDecorators::InrVolumeHonours(const char* name)
{
  // Colouring by the model's value (the Coloring group), the colour and opacity maps (the
  // transfer function), the volume's opacity unit distance, the transform (the mapper reads
  // the volume's matrix) and the volume's lighting (gradient shading: InrSceneTranslator).
  static const char* const honoured[] = { "ColorArrayName", "LookupTable", "ScalarOpacityFunction",
    "ScalarOpacityUnitDistance", "UseSeparateColorMap", "Position", "Scale", "Orientation",
    "Origin", "Shade", "Ambient", "Diffuse", "Specular", "SpecularPower" };
  for (const char* h : honoured)
  {
    if (name && std::strcmp(name, h) == 0)
    {
      return true;
    }
  }
  return false;
}

void pqInrPanelDecorators::createDefaultWidgetDecorators(pqPropertyWidget* widget)
{
  vtkSMProxy* proxy = widget ? widget->proxy() : nullptr;
  vtkSMProperty* property = widget ? widget->property() : nullptr;
  // Only representations that can be INR Volume (they carry its sub-proxy's state property).
  vtkSMProperty* inrState = proxy ? proxy->GetProperty("InrConverged") : nullptr;
  if (!property || !inrState)
  {
    return;
  }
  vtkSMProxy* owner = property->GetParent();
  const char* ownerName = owner ? owner->GetXMLName() : nullptr;
  if (!owner || owner == proxy)
  {
    return;  // the representation's own rows (Representation, axes grids) serve every kind
  }
  if (ownerName && std::strcmp(ownerName, kInrSubProxy) == 0)
  {
    // INR Volume's own rows do nothing for the other kinds: shown only with INR Volume.
    new pqInrRepresentationTypeDecorator(proxy, widget, true);
    return;
  }
  const char* name = proxy->GetPropertyName(property);
  if (InrVolumeHonours(name))
  {
    return;
  }
  new pqInrRepresentationTypeDecorator(proxy, widget, false);
}

pqInrRepresentationTypeDecorator::pqInrRepresentationTypeDecorator(
  vtkSMProxy* representation, pqPropertyWidget* parent, bool showOnlyWithInrVolume)
  : pqPropertyWidgetDecorator(nullptr, parent)
  , Representation(representation)
  , ShowOnlyWithInrVolume(showOnlyWithInrVolume)
{
  this->Type = representation->GetProperty("Representation");
  if (this->Type)
  {
    this->ObserverId = this->Type->AddObserver(vtkCommand::ModifiedEvent, this,
      &pqInrRepresentationTypeDecorator::visibilityChanged);
  }
}

pqInrRepresentationTypeDecorator::~pqInrRepresentationTypeDecorator()
{
  if (this->Type)
  {
    this->Type->RemoveObserver(this->ObserverId);
  }
}

bool pqInrRepresentationTypeDecorator::canShowWidget(bool) const
{
  return showsInrVolume(this->Representation) == this->ShowOnlyWithInrVolume;
}
