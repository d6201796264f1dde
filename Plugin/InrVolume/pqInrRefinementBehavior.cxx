#include "pqInrRefinementBehavior.h"

#include "pqApplicationCore.h"
#include "pqDataRepresentation.h"
#include "pqServerManagerModel.h"
#include "pqView.h"
#include "vtkDataObject.h"
#include "vtkPVArrayInformation.h"
#include "vtkPVDataInformation.h"
#include "vtkSMPVRepresentationProxy.h"
#include "vtkSMProperty.h"
#include "vtkSMPropertyHelper.h"
#include "vtkSMProxy.h"
#include "vtkSMSession.h"
#include "vtkSMTransferFunctionProxy.h"
#include "vtkClientServerStream.h"
#include "vtkPVSession.h"

#include <cstring>

namespace
{
bool isInrVolume(vtkSMProxy* proxy)
{
  vtkSMProperty* p = proxy ? proxy->GetProperty("Representation") : nullptr;
  const char* type = p ? vtkSMPropertyHelper(p).GetAsString() : nullptr;
  return type && std::strcmp(type, "INR Volume") == 0;
}

// Asks the representation object on the render server (the process that renders; the client's
// copy does not render in client/server mode, so information properties pulled from the client
// would say nothing) whether it is still refining.
bool stillRefining(vtkSMProxy* proxy)
{
  vtkSMProperty* prop = proxy->GetProperty("InrConverged");
  vtkSMProxy* inr = prop ? prop->GetParent() : nullptr;
  vtkSMSession* session = inr ? inr->GetSession() : nullptr;
  if (!session)
  {
    return false;
  }
  vtkClientServerStream stream;
  stream << vtkClientServerStream::Invoke << VTKOBJECT(inr) << "GetInrConverged"
         << vtkClientServerStream::End;
  session->ExecuteStream(vtkPVSession::RENDER_SERVER_ROOT, stream, false);
  const vtkClientServerStream& result = session->GetLastResult(vtkPVSession::RENDER_SERVER_ROOT);
  int converged = 1;
  if (result.GetNumberOfMessages() < 1 || !result.GetArgument(0, 0, &converged))
  {
    return false;
  }
  return converged == 0;
}
}

pqInrRefinementBehavior::pqInrRefinementBehavior(QObject* parent)
  : QObject(parent)
{
  this->Timer.setSingleShot(true);
  this->Timer.setInterval(15);  // let the event loop breathe between refinement renders
  QObject::connect(&this->Timer, &QTimer::timeout, this, &pqInrRefinementBehavior::refine);
}

pqInrRefinementBehavior::~pqInrRefinementBehavior() = default;

void pqInrRefinementBehavior::onStartup()
{
  pqServerManagerModel* smm = pqApplicationCore::instance()->getServerManagerModel();
  QObject::connect(smm, &pqServerManagerModel::viewAdded, this,
    &pqInrRefinementBehavior::onViewAdded);
  for (pqView* view : smm->findItems<pqView*>())
  {
    this->onViewAdded(view);
  }
}

void pqInrRefinementBehavior::onShutdown()
{
  this->Timer.stop();
  this->Pending.clear();
}

void pqInrRefinementBehavior::onViewAdded(pqView* view)
{
  QObject::connect(view, &pqView::endRender, this, &pqInrRefinementBehavior::onEndRender,
    Qt::UniqueConnection);
}

void pqInrRefinementBehavior::onEndRender()
{
  pqView* view = qobject_cast<pqView*>(this->sender());
  if (!view)
  {
    return;
  }
  for (const auto& v : this->Pending)
  {
    if (v == view)
    {
      if (!this->Timer.isActive())
      {
        this->Timer.start();
      }
      return;
    }
  }
  this->Pending.push_back(view);
  if (!this->Timer.isActive())
  {
    this->Timer.start();
  }
}

void pqInrRefinementBehavior::refine()
{
  const auto views = this->Pending;
  this->Pending.clear();
  for (const auto& view : views)
  {
    if (!view)
    {
      continue;
    }
    bool again = false;
    for (pqRepresentation* r : view->getRepresentations())
    {
      auto* repr = qobject_cast<pqDataRepresentation*>(r);
      if (!repr || !repr->isVisible())
      {
        continue;
      }
      vtkSMProxy* proxy = repr->getProxy();
      if (!isInrVolume(proxy))
      {
        continue;
      }
      if (!this->AutoColored.contains(proxy))
      {
        this->AutoColored.insert(proxy);
        if (!vtkSMPVRepresentationProxy::GetUsingScalarColoring(proxy) &&
          vtkSMPVRepresentationProxy::SetScalarColoring(proxy, "value", vtkDataObject::POINT))
        {
          vtkPVDataInformation* info = repr->getInputDataInformation();
          vtkPVArrayInformation* range =
            info ? info->GetArrayInformation("InrValueRange", vtkDataObject::FIELD) : nullptr;
          vtkSMProxy* lut = vtkSMPropertyHelper(proxy, "LookupTable", true).GetAsProxy();
          if (range && lut)
          {
            double vr[2];
            range->GetComponentRange(0, vr);
            if (auto* tf = vtkSMTransferFunctionProxy::SafeDownCast(lut))
            {
              tf->RescaleTransferFunction(vr[0], vr[1], false);
            }
            vtkSMProxy* sof = vtkSMPropertyHelper(lut, "ScalarOpacityFunction", true).GetAsProxy();
            if (auto* otf = vtkSMTransferFunctionProxy::SafeDownCast(sof))
            {
              otf->RescaleTransferFunction(vr[0], vr[1], false);
            }
          }
          proxy->UpdateVTKObjects();
          again = true;
          continue;
        }
      }
      // Progressive refinement off: one frame per render, nothing re-rendered from here (checked
      // on the client's property, no server round trip).
      if (vtkSMProperty* on = proxy->GetProperty("InrProgressiveRefinement"))
      {
        if (vtkSMPropertyHelper(on).GetAsInt() == 0)
        {
          continue;
        }
      }
      if (stillRefining(proxy))
      {
        again = true;
      }
    }
    if (again)
    {
      // A direct render from this (idle-time) timer callback: pqView::render()'s own deferred
      // timer is held back while test playback pauses, and we are already outside any render.
      view->forceRender();
    }
  }
}
