#include "pqInrRefinementBehavior.h"

#include "pqAnimationManager.h"
#include "vtkInrVolumeMapper.h"
#include "vtkInrVolumeRepresentation.h"
#include "vtkRenderWindow.h"
#include "vtkSMViewProxy.h"
#include "vtkSMRenderViewProxy.h"
#include "vtkRenderWindowInteractor.h"
#include "pqCoreUtilities.h"
#include "pqApplicationCore.h"
#include "pqDataRepresentation.h"
#include "pqPVApplicationCore.h"
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
#include "vtkSMTransferFunctionPresets.h"
#include "vtkSMTransferFunctionProxy.h"
#include "vtkSMSourceProxy.h"
#include "vtkSMDoubleRangeDomain.h"
#include "vtkSMIntRangeDomain.h"
#include "vtkSMPropertyIterator.h"
#include "vtkSMVectorProperty.h"
#include "vtkCommand.h"
#include "vtk_jsoncpp.h"
#include "vtkClientServerStream.h"
#include "vtkPVSession.h"

#include "vtkSmartPointer.h"

#include <QMainWindow>
#include <QStatusBar>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>

namespace
{
bool isInrVolume(vtkSMProxy* proxy)
{
  vtkSMProperty* p = proxy ? proxy->GetProperty("Representation") : nullptr;
  const char* type = p ? vtkSMPropertyHelper(p).GetAsString() : nullptr;
  return type && std::strcmp(type, "INR Volume") == 0;
}

// Asks the representation object on the render server (the process that renders; the client's
// copy does not render in client/server mode) for an int (`method` of
// vtkInrVolumeRepresentation); `fallback` when it cannot be asked. One call, without the pull
// of every information property that UpdatePropertyInformation makes (which
// vtkSMInrVolumeRepresentationProxy also sends to the render server).
int askRenderServer(vtkSMProxy* proxy, const char* method, int fallback)
{
  vtkSMProperty* prop = proxy->GetProperty("InrConverged");
  vtkSMProxy* inr = prop ? prop->GetParent() : nullptr;
  vtkSMSession* session = inr ? inr->GetSession() : nullptr;
  if (!session)
  {
    return fallback;
  }
  vtkClientServerStream stream;
  stream << vtkClientServerStream::Invoke << VTKOBJECT(inr) << method
         << vtkClientServerStream::End;
  session->ExecuteStream(vtkPVSession::RENDER_SERVER_ROOT, stream, false);
  const vtkClientServerStream& result = session->GetLastResult(vtkPVSession::RENDER_SERVER_ROOT);
  int value = fallback;
  if (result.GetNumberOfMessages() < 1 || !result.GetArgument(0, 0, &value))
  {
    return fallback;
  }
  return value;
}

// While the animation plays, each tick of ParaView's animation scene renders every view itself
// (vtkSMAnimationScene::TickInternal: StillRenderAllViews), after processing the GUI's events
// (pqVCRController::onTick). A refinement render from this behaviour, fired inside those events,
// would render the new time once more just before the tick's own render: two renders per time
// step, the second at full resolution. So refinement waits until playback ends.
bool animationPlaying()
{
  pqPVApplicationCore* core = pqPVApplicationCore::instance();
  pqAnimationManager* animation = core ? core->animationManager() : nullptr;
  return animation && animation->animationPlaying();
}

// INR_VOLUME_LOD_LOG=1 (the mapper's per-render log) also logs what this behaviour does.
bool lodLogOn()
{
  const char* log = std::getenv("INR_VOLUME_LOD_LOG");
  return log && log[0] && std::strcmp(log, "0") != 0;
}

bool stillRefining(vtkSMProxy* proxy)
{
  return askRenderServer(proxy, "GetInrConverged", 1) == 0;
}

// Whether the mapper's worker thread is refining (or building ahead) and has not finished: a
// render now would draw nothing new. Known in the builtin session only (the process that renders
// is this one; a render server does not refine in the background).
bool workerBusy(vtkSMProxy* proxy)
{
  vtkSMProperty* prop = proxy->GetProperty("InrConverged");
  vtkSMProxy* inr = prop ? prop->GetParent() : nullptr;
  auto* representation =
    inr ? vtkInrVolumeRepresentation::SafeDownCast(inr->GetClientSideObject()) : nullptr;
  vtkInrVolumeMapper* mapper = representation ? representation->GetInrMapper() : nullptr;
  return mapper && mapper->GetBackgroundWorkRunning() != 0;
}

// After an interactive (reduced) frame the user is probably still dragging the camera or the
// time slider: the full-resolution refinement waits this long without a new render, so the next
// drag step gets another fast frame instead of waiting for a full-resolution one. (A camera drag
// ends with ParaView's own still render, which starts the refinement at once.)
constexpr int kInteractionSettleMs = 300;
// While a camera drag pauses with the button down, the reduced image is refined up to this many
// frames (later renders would only polish an image the release replaces).
constexpr int kHeldDragFrames = 16;
// While the mapper's worker prepares the next image, how often the loop looks whether it is done.
constexpr int kWorkerPollMs = 10;
// Between refinement renders: lets the event loop breathe.
constexpr int kRefinePauseMs = 15;
// The panel's state is pulled from the server this long after a render (a burst of refinement
// renders refreshes it about four times a second).
constexpr int kStateRefreshMs = 250;
// The event-loop watch (INR_VOLUME_EVENT_LOOP_LOG): its tick, and the stalls it logs.
constexpr int kEventLoopWatchMs = 5;
constexpr double kEventLoopStallMs = 40.0;
}

pqInrRefinementBehavior::pqInrRefinementBehavior(QObject* parent)
  : QObject(parent)
{
  this->Timer.setSingleShot(true);
  this->Timer.setInterval(kRefinePauseMs);
  QObject::connect(&this->Timer, &QTimer::timeout, this, &pqInrRefinementBehavior::refine);
  this->StateTimer.setSingleShot(true);
  this->StateTimer.setInterval(kStateRefreshMs);
  QObject::connect(
    &this->StateTimer, &QTimer::timeout, this, &pqInrRefinementBehavior::refreshState);
  const char* watchLog = std::getenv("INR_VOLUME_EVENT_LOOP_LOG");
  if (watchLog && watchLog[0])
  {
    this->EventLoopLog = std::fopen(watchLog, "w");
    if (this->EventLoopLog)
    {
      this->EventLoopWatch.setTimerType(Qt::PreciseTimer);
      this->EventLoopWatch.setInterval(kEventLoopWatchMs);
      QObject::connect(
        &this->EventLoopWatch, &QTimer::timeout, this, &pqInrRefinementBehavior::watchEventLoop);
      this->SinceWatch.start();
      this->EventLoopWatch.start();
    }
  }
}

// A tick of the event-loop watch: the time since the previous tick, beyond the timer's interval,
// is how long the loop could not run (the timer fires as soon as the loop runs again).
void pqInrRefinementBehavior::watchEventLoop()
{
  const qint64 ns = this->SinceWatch.nsecsElapsed();
  this->SinceWatch.start();
  const double ms = 1e-6 * double(ns);
  if (ms > kEventLoopStallMs && this->EventLoopLog)
  {
    timespec now{};
    clock_gettime(CLOCK_MONOTONIC, &now);
    std::fprintf(this->EventLoopLog, "block_ms=%.1f end=%.6f\n", ms,
      double(now.tv_sec) + 1e-9 * double(now.tv_nsec));
    std::fflush(this->EventLoopLog);
  }
}

pqInrRefinementBehavior::~pqInrRefinementBehavior()
{
  if (this->EventLoopLog)
  {
    std::fclose(this->EventLoopLog);
  }
}

void pqInrRefinementBehavior::onStartup()
{
  // The GUI renders again by itself: macrocell builds may run in the background (builtin
  // session; a pvserver process keeps building in its render preparation).
  vtkInrVolumeMapper::SetBackgroundMacrocellBuilds(true);
  pqServerManagerModel* smm = pqApplicationCore::instance()->getServerManagerModel();
  QObject::connect(smm, &pqServerManagerModel::viewAdded, this,
    &pqInrRefinementBehavior::onViewAdded);
  QObject::connect(smm, &pqServerManagerModel::representationAdded, this,
    &pqInrRefinementBehavior::onRepresentationAdded);
  for (pqView* view : smm->findItems<pqView*>())
  {
    this->onViewAdded(view);
  }
}

void pqInrRefinementBehavior::onShutdown()
{
  this->Timer.stop();
  this->StateTimer.stop();
  this->Pending.clear();
}

void pqInrRefinementBehavior::onRepresentationAdded(pqRepresentation* added)
{
  auto* repr = qobject_cast<pqDataRepresentation*>(added);
  vtkSMProxy* proxy = repr ? repr->getProxy() : nullptr;
  vtkSMProperty* type = proxy ? proxy->GetProperty("Representation") : nullptr;
  if (!type)
  {
    return;
  }
  // Coloured as soon as it becomes INR Volume, before its first render (the render after Apply
  // or after the representation menu changed follows these calls): one image, no restart.
  pqCoreUtilities::connect(type, vtkCommand::ModifiedEvent, this, SLOT(onRepresentationTypeChanged()));
  // The INR Volume settings: a value the engine would refuse never stays in the panel.
  if (vtkSMProperty* state = proxy->GetProperty("InrConverged"))
  {
    vtkSMProxy* inr = state->GetParent();
    vtkSmartPointer<vtkSMPropertyIterator> it;
    it.TakeReference(inr->NewPropertyIterator());
    for (it->Begin(); !it->IsAtEnd(); it->Next())
    {
      vtkSMProperty* p = it->GetProperty();
      if (p && !p->GetInformationOnly() && (p->FindDomain<vtkSMIntRangeDomain>() ||
                                             p->FindDomain<vtkSMDoubleRangeDomain>()))
      {
        pqCoreUtilities::connect(
          p, vtkCommand::ModifiedEvent, this, SLOT(onSettingModified(vtkObject*)));
      }
    }
  }
  if (vtkSMProperty* input = proxy->GetProperty("Input"))
  {
    pqCoreUtilities::connect(
      input, vtkCommand::ModifiedEvent, this, SLOT(onRepresentationTypeChanged()));
  }
  this->colorByModel(repr);
}

// A setting outside its property's range (the panel's text boxes accept any number), or a Skip
// Block that is not 0 or a power of two, is replaced at once by the nearest valid value, and the
// status bar says so: the panel never holds a value the engine refuses (the engine would keep its
// previous value and report an error on every rebuild).
void pqInrRefinementBehavior::onSettingModified(vtkObject* caller)
{
  auto* prop = vtkSMVectorProperty::SafeDownCast(caller);
  if (!prop || this->FixingSetting)
  {
    return;
  }
  vtkSMPropertyHelper helper(prop);
  if (helper.GetNumberOfElements() != 1)
  {
    return;
  }
  const double asked = helper.GetAsDouble(0);
  double value = asked;
  int hasMin = 0, hasMax = 0;
  double lo = 0.0, hi = 0.0;
  if (auto* d = prop->FindDomain<vtkSMDoubleRangeDomain>())
  {
    lo = d->GetMinimum(0, hasMin);
    hi = d->GetMaximum(0, hasMax);
  }
  else if (auto* i = prop->FindDomain<vtkSMIntRangeDomain>())
  {
    lo = i->GetMinimum(0, hasMin);
    hi = i->GetMaximum(0, hasMax);
  }
  if (hasMin && value < lo)
  {
    value = lo;
  }
  if (hasMax && value > hi)
  {
    value = hi;
  }
  if (std::strcmp(prop->GetXMLName(), "InrSkipBlock") == 0 && value > 0.0)
  {
    int cells = 1;
    while (cells * 2 <= int(value))
    {
      cells *= 2;  // a power of two, at most the asked value
    }
    value = cells;
  }
  if (!(value == asked))  // also NaN
  {
    this->FixingSetting = true;
    helper.Set(0, value);
    this->FixingSetting = false;
    const char* label = prop->GetXMLLabel() ? prop->GetXMLLabel() : prop->GetXMLName();
    QString message = QString("INR Volume: %1 = %2 is not allowed").arg(label).arg(asked);
    message += hasMin && hasMax ? QString(" (%1 to %2").arg(lo).arg(hi) : QString(" (");
    if (std::strcmp(prop->GetXMLName(), "InrSkipBlock") == 0)
    {
      message += ", 0 or a power of two";
    }
    message += QString("): set to %1").arg(value);
    if (auto* window = qobject_cast<QMainWindow*>(pqCoreUtilities::mainWidget()))
    {
      window->statusBar()->showMessage(message, 8000);
    }
  }
}

void pqInrRefinementBehavior::onRepresentationTypeChanged()
{
  pqServerManagerModel* smm = pqApplicationCore::instance()->getServerManagerModel();
  for (pqDataRepresentation* repr : smm->findItems<pqDataRepresentation*>())
  {
    this->colorByModel(repr);
  }
}

// Once per representation, when it is (or becomes) INR Volume: colour it by "value" with the
// model's own colour and opacity map when the reader found one (InrTransferFunction: the
// *.tf.json preset beside the model; added to ParaView's presets under its name, applied with
// its own value range, automatic rescaling off so the preview grid's range never replaces it),
// else with ParaView's default map rescaled to the model's value range (InrValueRange).
bool pqInrRefinementBehavior::colorByModel(pqDataRepresentation* repr)
{
  vtkSMProxy* proxy = repr ? repr->getProxy() : nullptr;
  if (!proxy || !isInrVolume(proxy) || this->AutoColored.contains(proxy))
  {
    return false;
  }
  // The reader, from the server-manager property (set before the Qt-side input link exists).
  vtkSMProperty* inputProp = proxy->GetProperty("Input");
  auto* reader = inputProp ? vtkSMSourceProxy::SafeDownCast(vtkSMPropertyHelper(inputProp).GetAsProxy())
                           : nullptr;
  if (!reader)
  {
    return false;  // not connected yet: the Input property's change calls again
  }
  this->AutoColored.insert(proxy);
  QElapsedTimer took;
  took.start();
  struct Report
  {
    QElapsedTimer& took;
    ~Report()
    {
      if (lodLogOn())
      {
        std::fprintf(stderr, "INR Volume refinement: colour map set up in %lld ms\n",
          static_cast<long long>(this->took.elapsed()));
      }
    }
  } report{ took };
  if (!vtkSMPVRepresentationProxy::GetUsingScalarColoring(proxy) &&
    !vtkSMPVRepresentationProxy::SetScalarColoring(proxy, "value", vtkDataObject::POINT))
  {
    return false;
  }
  vtkSMProxy* lut = vtkSMPropertyHelper(proxy, "LookupTable", true).GetAsProxy();
  vtkSMProxy* sof = lut ? vtkSMPropertyHelper(lut, "ScalarOpacityFunction", true).GetAsProxy() : nullptr;
  if (!lut)
  {
    return false;
  }
  bool applied = false;
  vtkSMProperty* tfProp = reader->GetProperty("InrTransferFunction");
  if (tfProp)
  {
    reader->UpdatePropertyInformation(tfProp);
    const char* text = vtkSMPropertyHelper(tfProp).GetAsString();
    const std::string json = text ? text : "";
    Json::CharReaderBuilder builder;
    std::unique_ptr<Json::CharReader> parser(builder.newCharReader());
    Json::Value root;
    std::string errors;
    if (!json.empty() && parser->parse(json.data(), json.data() + json.size(), &root, &errors))
    {
      const Json::Value preset = root.isArray() && root.size() > 0 ? root[0] : root;
      if (preset.isObject() && preset.isMember("RGBPoints"))
      {
        const std::string name =
          preset.isMember("Name") ? preset["Name"].asString() : std::string("INR model");
        // A preset the user can pick again: added once the view has drawn (ParaView's preset
        // list loads and parses all its presets on first use, which would delay the first
        // image).
        QTimer::singleShot(0, [name, preset]()
          {
            if (auto* presets = vtkSMTransferFunctionPresets::GetInstance())
            {
              presets->AddPreset(name.c_str(), preset);
            }
          });
        applied = vtkSMTransferFunctionProxy::ApplyPreset(lut, preset, false);
        if (sof && preset.isMember("Points"))
        {
          vtkSMTransferFunctionProxy::ApplyPreset(sof, preset, false);
        }
        if (lut->GetProperty("AutomaticRescaleRangeMode"))
        {
          vtkSMPropertyHelper(lut, "AutomaticRescaleRangeMode").Set(-1);  // Never
        }
      }
    }
  }
  if (!applied)
  {
    vtkPVDataInformation* info = reader->GetDataInformation(
      static_cast<unsigned int>(vtkSMPropertyHelper(inputProp).GetOutputPort()));
    vtkPVArrayInformation* range =
      info ? info->GetArrayInformation("InrValueRange", vtkDataObject::FIELD) : nullptr;
    if (range)
    {
      double vr[2];
      range->GetComponentRange(0, vr);
      if (auto* tf = vtkSMTransferFunctionProxy::SafeDownCast(lut))
      {
        tf->RescaleTransferFunction(vr[0], vr[1], false);
      }
      if (auto* otf = vtkSMTransferFunctionProxy::SafeDownCast(sof))
      {
        otf->RescaleTransferFunction(vr[0], vr[1], false);
      }
    }
  }
  lut->UpdateVTKObjects();
  if (sof)
  {
    sof->UpdateVTKObjects();
  }
  proxy->UpdateVTKObjects();
  return true;
}

void pqInrRefinementBehavior::onViewAdded(pqView* view)
{
  QObject::connect(view, &pqView::endRender, this, &pqInrRefinementBehavior::onEndRender,
    Qt::UniqueConnection);
  // A camera drag in progress (button down): the interactor's Start/EndInteractionEvent, which
  // ParaView's own interactor helper also follows to pick interactive or still renders.
  auto* renderView = vtkSMRenderViewProxy::SafeDownCast(view->getViewProxy());
  if (vtkRenderWindowInteractor* interactor = renderView ? renderView->GetInteractor() : nullptr)
  {
    for (unsigned long event : { vtkCommand::StartInteractionEvent, vtkCommand::EndInteractionEvent })
    {
      pqCoreUtilities::connect(
        interactor, event, this, SLOT(onInteraction(vtkObject*, unsigned long)));
    }
  }
}

void pqInrRefinementBehavior::onInteraction(vtkObject* interactor, unsigned long event)
{
  if (event == vtkCommand::StartInteractionEvent)
  {
    this->Interacting.insert(interactor);
  }
  else
  {
    this->Interacting.remove(interactor);
  }
}

void pqInrRefinementBehavior::onEndRender()
{
  pqView* view = qobject_cast<pqView*>(this->sender());
  if (!view)
  {
    return;
  }
  this->SinceRender.start();
  if (!this->StateTimer.isActive())
  {
    this->StateTimer.start();
  }
  for (const auto& v : this->Pending)
  {
    if (v == view)
    {
      if (!this->Timer.isActive())
      {
        this->Timer.start(kRefinePauseMs);
      }
      return;
    }
  }
  this->Pending.push_back(view);
  if (!this->Timer.isActive())
  {
    this->Timer.start(kRefinePauseMs);
  }
}

void pqInrRefinementBehavior::refine()
{
  if (animationPlaying())
  {
    // Every pending view is rendered by the next tick anyway; look again once playback ended.
    this->Timer.start(kInteractionSettleMs);
    return;
  }
  const auto views = this->Pending;
  this->Pending.clear();
  const bool lodLog = lodLogOn();
  for (const auto& view : views)
  {
    if (!view)
    {
      continue;
    }
    // Never a render inside another one: this timer can fire from events processed during a
    // render or an animation tick (pqVCRController processes events in its tick).
    vtkSMViewProxy* viewProxy = view->getViewProxy();
    vtkRenderWindow* window = viewProxy ? viewProxy->GetRenderWindow() : nullptr;
    if (window && window->CheckInRenderStatus())
    {
      this->Pending.push_back(view);
      this->Timer.start(kInteractionSettleMs);
      continue;
    }
    bool again = false;
    bool settling = false;
    bool waiting = false;   // a worker thread prepares the next image: nothing to render yet
    bool reduced = false;   // the last render drew a reduced (level-of-detail) image
    int reducedFrames = 0;  // frames that reduced image holds
    auto* renderView = vtkSMRenderViewProxy::SafeDownCast(viewProxy);
    const bool dragging =
      renderView && renderView->GetInteractor() && this->Interacting.contains(renderView->GetInteractor());
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
      if (this->colorByModel(repr))
      {
        again = true;
        continue;
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
        const bool interactive = askRenderServer(proxy, "GetInrLastRenderInteractive", 0) != 0;
        settling = settling ||
          (interactive && this->SinceRender.isValid() &&
            this->SinceRender.elapsed() < kInteractionSettleMs);
        waiting = waiting || workerBusy(proxy);
        if (interactive)
        {
          reduced = true;
          reducedFrames = std::max(reducedFrames, askRenderServer(proxy, "GetInrAccumulatedFrames", 0));
        }
      }
    }
    if (again && !settling && dragging && reduced)
    {
      // The mouse button is still down: the drag may resume at any moment. Refine the reduced
      // image (each render within the level-of-detail budget) a few frames, then wait for the
      // release, whose still render starts the full-resolution refinement.
      if (reducedFrames < kHeldDragFrames && renderView)
      {
        if (lodLog)
        {
          std::fprintf(stderr, "INR Volume refinement: drag paused, refining the reduced image\n");
        }
        renderView->InteractiveRender();
      }
      continue;
    }
    if (again && !settling && waiting && !dragging)
    {
      // Look again shortly; render once the worker's step is done.
      this->Pending.push_back(view);
      this->Timer.start(kWorkerPollMs);
      continue;
    }
    if (again && settling)
    {
      this->Pending.push_back(view);
      this->Timer.start(
        std::max(1, kInteractionSettleMs - static_cast<int>(this->SinceRender.elapsed())));
    }
    else if (again)
    {
      if (lodLog)
      {
        std::fprintf(stderr, "INR Volume refinement: rendering the view again\n");
      }
      // A direct render from this (idle-time) timer callback: pqView::render()'s own deferred
      // timer is held back while test playback pauses, and we are already outside any render.
      view->forceRender();
    }
  }
}

// Pulls the information properties of every visible INR Volume representation (the panel's
// widgets follow them) and shows the refinement state of the first one in the status bar.
void pqInrRefinementBehavior::refreshState()
{
  pqServerManagerModel* smm = pqApplicationCore::instance()->getServerManagerModel();
  QString status;
  for (pqView* view : smm->findItems<pqView*>())
  {
    for (pqRepresentation* r : view->getRepresentations())
    {
      auto* repr = qobject_cast<pqDataRepresentation*>(r);
      if (!repr || !repr->isVisible() || !isInrVolume(repr->getProxy()))
      {
        continue;
      }
      vtkSMProperty* prop = repr->getProxy()->GetProperty("InrRefinementState");
      vtkSMProxy* inr = prop ? prop->GetParent() : nullptr;
      if (!inr)
      {
        continue;
      }
      inr->UpdatePropertyInformation();
      if (status.isEmpty())
      {
        const char* state = vtkSMPropertyHelper(prop).GetAsString();
        status = QString("INR Volume: %1").arg(QString::fromUtf8(state ? state : ""));
      }
    }
  }
  auto* window = qobject_cast<QMainWindow*>(pqCoreUtilities::mainWidget());
  if (window && !status.isEmpty())
  {
    window->statusBar()->showMessage(status, 4000);
  }
}
