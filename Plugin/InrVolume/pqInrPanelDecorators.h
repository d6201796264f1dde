/**
 * @class pqInrPanelDecorators
 * @brief Hides, while a representation is shown as "INR Volume", the panel rows of the image
 * representation's other kinds (Surface, Points, Slice, ParaView's Volume, ...) that do nothing
 * for INR Volume.
 *
 * ParaView's image representation (UniformGridRepresentation) is one proxy that exposes the
 * properties of all its kinds; its XML hides few of them per kind, so the INR Volume groups came
 * after about 40 rows of surface styling, lighting, textures and LIC settings. ParaView 5.11
 * asks every plugin's pqPropertyWidgetInterface for default decorators of each property widget it
 * creates (createDefaultWidgetDecorators), which lets this plugin decorate the rows of proxies it
 * did not define, without touching ParaView's XML. A row is hidden when the representation is INR
 * Volume and its property belongs to another kind's sub-proxy, unless INR Volume honours it
 * (InrVolumeHonours: colouring, the colour and opacity maps, the opacity unit distance, the
 * transform, the volume's lighting). Rows of the representation itself (Representation, axes
 * grids) stay; every row comes back when another representation type is chosen, and INR
 * Volume's own rows then hide (they do nothing for Surface, Slice, ParaView's Volume, ...). The
 * panel's search box still finds a hidden one only after switching type (as for ParaView's own
 * hidden rows).
 *
 * The rows of ParaView's Volume that INR Volume honours (Blend Mode, Isosurfaces, Slice Type,
 * Use Cropping, the cropping box, ...) carry ParaView's own decorators, which show them only for
 * "Volume" (and NVIDIA IndeX); a panel shows a row only when every decorator agrees, so another
 * decorator cannot show it. Those decorators come from the property groups' hints after this
 * interface is asked (and the cropping box is a group row, for which it is never asked), so a
 * deferred pass over the panel, once its rows exist, makes each such decorator again from a copy
 * of its XML in which "Representation is Volume" reads "Volume or INR Volume": the rows show for
 * INR Volume in the places and under the conditions (Isosurfaces only with Blend Mode
 * Isosurface, the box only with Use Cropping, ...) that ParaView gives them for Volume.
 */
#ifndef pqInrPanelDecorators_h
#define pqInrPanelDecorators_h

#include "pqPropertyWidgetDecorator.h"
#include "pqPropertyWidgetInterface.h"

#include "vtkWeakPointer.h"

#include <QObject>

class vtkSMProperty;
class vtkSMProxy;

class pqInrPanelDecorators : public QObject, public pqPropertyWidgetInterface
{
  Q_OBJECT
  Q_INTERFACES(pqPropertyWidgetInterface)
public:
  pqInrPanelDecorators(QObject* parent = nullptr);
  ~pqInrPanelDecorators() override;

  void createDefaultWidgetDecorators(pqPropertyWidget* widget) override;

  /// Whether INR Volume uses the property `name` of another representation kind's sub-proxy.
  static bool InrVolumeHonours(const char* name);
};

/// The decorator itself: shows its row only while the representation is INR Volume
/// (`showOnlyWithInrVolume`, INR Volume's own rows) or only while it is not (the other kinds').
class pqInrRepresentationTypeDecorator : public pqPropertyWidgetDecorator
{
  Q_OBJECT
public:
  pqInrRepresentationTypeDecorator(
    vtkSMProxy* representation, pqPropertyWidget* parent, bool showOnlyWithInrVolume);
  ~pqInrRepresentationTypeDecorator() override;
  bool canShowWidget(bool showAdvanced) const override;

private:
  vtkWeakPointer<vtkSMProxy> Representation;
  bool ShowOnlyWithInrVolume;
  vtkWeakPointer<vtkSMProperty> Type;  // its "Representation" property, observed
  unsigned long ObserverId = 0;
};

#endif
