#include "pqInrPanelDecorators.h"

#include "pqInteractivePropertyWidgetAbstract.h"
#include "pqPropertyWidget.h"
#include "pqProxyWidget.h"
#include "vtkCollection.h"
#include "vtkCommand.h"
#include "vtkNew.h"
#include "vtkPVXMLElement.h"
#include "vtkSMProperty.h"
#include "vtkSMPropertyGroup.h"
#include "vtkSMPropertyHelper.h"
#include "vtkSMProxy.h"
#include "vtkSmartPointer.h"

#include <QPointer>
#include <QTimer>

#include <cstring>
#include <vector>

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

// The XML a decorator was made from (pqPropertyWidgetDecorator::xml is protected: read through a
// pointer to that member formed in a subclass, as C++ allows).
struct DecoratorXml : pqPropertyWidgetDecorator
{
  static vtkPVXMLElement* Of(const pqPropertyWidgetDecorator* decorator)
  {
    vtkPVXMLElement* (pqPropertyWidgetDecorator::*get)() const = &DecoratorXml::xml;
    return (decorator->*get)();
  }
};

bool is(const char* a, const char* b)
{
  return a && b && std::strcmp(a, b) == 0;
}

// ParaView's test "the representation is Volume": <PropertyWidgetDecorator type="GenericDecorator"
// mode="visibility" property="Representation" value="Volume" /> (not inverted).
bool testsForVolume(vtkPVXMLElement* e)
{
  return is(e->GetName(), "PropertyWidgetDecorator") && is(e->GetAttribute("type"), "GenericDecorator") &&
    is(e->GetAttribute("mode"), "visibility") && is(e->GetAttribute("property"), "Representation") &&
    is(e->GetAttribute("value"), "Volume") && !is(e->GetAttribute("inverse"), "1");
}

// `test` OR the same test for "INR Volume" (a new CompositeDecorator element).
vtkSmartPointer<vtkPVXMLElement> volumeOrInrVolume(vtkPVXMLElement* test)
{
  auto inr = vtkSmartPointer<vtkPVXMLElement>::New();
  test->CopyTo(inr);
  inr->SetAttribute("value", "INR Volume");
  auto volume = vtkSmartPointer<vtkPVXMLElement>::New();
  test->CopyTo(volume);
  vtkNew<vtkPVXMLElement> either;
  either->SetName("Expression");
  either->AddAttribute("type", "or");
  either->AddNestedElement(volume);
  either->AddNestedElement(inr);
  auto composite = vtkSmartPointer<vtkPVXMLElement>::New();
  composite->SetName("PropertyWidgetDecorator");
  composite->AddAttribute("type", "CompositeDecorator");
  composite->AddNestedElement(either);
  return composite;
}

// Replaces, below `parent`, every "Representation is Volume" test by "Volume or INR Volume";
// returns how many.
int widenVolumeTests(vtkPVXMLElement* parent)
{
  int widened = 0;
  for (unsigned i = 0; i < parent->GetNumberOfNestedElements(); ++i)
  {
    vtkPVXMLElement* child = parent->GetNestedElement(i);
    if (testsForVolume(child))
    {
      parent->ReplaceNestedElement(child, volumeOrInrVolume(child));
      ++widened;
    }
    else
    {
      widened += widenVolumeTests(child);
    }
  }
  return widened;
}

// Whether the row `widget` edits a property of ParaView's Volume that INR Volume honours: a
// property row, or a group row (the cropping box) any of whose properties it honours.
bool honouredVolumeRow(pqPropertyWidget* widget)
{
  vtkSMProxy* proxy = widget->proxy();
  if (!proxy)
  {
    return false;
  }
  if (vtkSMProperty* property = widget->property())
  {
    return pqInrPanelDecorators::InrVolumeHonours(proxy->GetPropertyName(property));
  }
  auto* group = qobject_cast<pqInteractivePropertyWidgetAbstract*>(widget);
  vtkSMPropertyGroup* smgroup = group ? group->propertyGroup() : nullptr;
  for (unsigned i = 0; smgroup && i < smgroup->GetNumberOfProperties(); ++i)
  {
    if (pqInrPanelDecorators::InrVolumeHonours(proxy->GetPropertyName(smgroup->GetProperty(i))))
    {
      return true;
    }
  }
  return false;
}

// The deferred pass over one panel (see the class comment): every decorator of an honoured
// Volume row that tests "Representation is Volume" is made again from a copy of its XML in which
// that test reads "Volume or INR Volume"; the new decorators report to the panel.
void showVolumeRowsForInrVolume(pqProxyWidget* panel)
{
  bool changed = false;
  for (pqPropertyWidget* widget : panel->findChildren<pqPropertyWidget*>())
  {
    if (!honouredVolumeRow(widget))
    {
      continue;
    }
    const QList<QPointer<pqPropertyWidgetDecorator>> decorators = widget->decorators();
    for (const QPointer<pqPropertyWidgetDecorator>& decorator : decorators)
    {
      vtkPVXMLElement* xml = decorator ? DecoratorXml::Of(decorator) : nullptr;
      if (!xml)
      {
        continue;  // a decorator made in code (ours among them)
      }
      auto copy = vtkSmartPointer<vtkPVXMLElement>::New();
      xml->CopyTo(copy);
      if (testsForVolume(copy))
      {
        copy = volumeOrInrVolume(copy);
      }
      else if (widenVolumeTests(copy) == 0)
      {
        continue;
      }
      // (The decorator keeps its XML: the copy lives as long as it does.)
      pqPropertyWidgetDecorator* widened = pqPropertyWidgetDecorator::create(copy, widget);
      if (!widened)
      {
        continue;  // (ParaView said why) the row keeps ParaView's own decorator
      }
      QObject::connect(widened, &pqPropertyWidgetDecorator::visibilityChanged, panel,
        &pqProxyWidget::updatePanel);
      QObject::connect(widened, &pqPropertyWidgetDecorator::enableStateChanged, panel,
        &pqProxyWidget::updatePanel);
      delete decorator.data();  // it takes itself off the widget's list
      changed = true;
    }
  }
  if (changed)
  {
    panel->updatePanel();
  }
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
  // the volume's matrix), the volume's lighting (gradient shading: InrSceneTranslator), the
  // blend modes with their isovalues, slice plane and cropping box (InrBlendTranslator) and the
  // 2D transfer function over the gradient magnitude (InrSceneTranslator::Transfer2D).
  static const char* const honoured[] = { "ColorArrayName", "LookupTable", "ScalarOpacityFunction",
    "ScalarOpacityUnitDistance", "UseSeparateColorMap", "Position", "Scale", "Orientation",
    "Origin", "Shade", "Ambient", "Diffuse", "Specular", "SpecularPower", "BlendMode",
    "IsosurfaceValues", "SliceFunction", "UseCropping", "CroppingOrigin", "CroppingScale",
    "UseTransfer2D" };
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
  // Once per panel, after ParaView has added its own decorators (those of the property groups
  // come after this call): show the Volume rows INR Volume honours (showVolumeRowsForInrVolume).
  auto* panel = qobject_cast<pqProxyWidget*>(widget->parent());
  if (panel && !panel->property("inrVolumeRowsPass").toBool())
  {
    panel->setProperty("inrVolumeRowsPass", true);
    QPointer<pqProxyWidget> guarded(panel);
    QTimer::singleShot(0, panel, [guarded]() {
      if (guarded)
      {
        showVolumeRowsForInrVolume(guarded);
      }
    });
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
