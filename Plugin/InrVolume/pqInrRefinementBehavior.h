/**
 * @class pqInrRefinementBehavior
 * @brief GUI-side progressive refinement for the "INR Volume" representation (auto-start).
 *
 * ParaView re-renders a view only when something changes; our mapper adds at least one frame per
 * render. After every render of a render view, this behaviour asks each visible INR Volume
 * representation (information property "InrConverged", pulled from the rendering server, so it
 * works through pvserver too) whether it is still refining, and if so schedules another render
 * after a short pause (event loop first, so the UI never freezes). Any change re-renders through
 * ParaView as usual; the mapper restarts accumulation and this loop picks it up again. The loop
 * stops by itself at convergence or at the representation's Maximum Frames, and never starts for a
 * representation whose Progressive Refinement is off (one frame per render). After an interactive
 * (reduced-resolution) frame it waits until no render came for a short while, so a camera or
 * time-slider drag keeps getting fast frames. While a camera drag holds the mouse button down
 * without moving, it refines the reduced image with further reduced (interactive) renders, each
 * within the level-of-detail budget, up to a few frames, instead of a full-resolution render
 * that would hold the event loop for a whole frame when the drag resumes; the full-resolution
 * refinement starts with ParaView's still render at the button's release.
 *
 * It also colours an INR Volume representation by its "value" array as soon as it is shown as
 * INR Volume (before its first render: no restart of the accumulation), with the model's own
 * colour and opacity map when one ships beside it (the reader's InrTransferFunction: the
 * *.tf.json preset, also added to ParaView's presets), else ParaView's default map rescaled to
 * the model's value range (field array "InrValueRange"), so ParaView's colour map editor is the
 * transfer function from the start (once per representation; a later choice of the user is
 * kept).
 *
 * Settings: a value outside an INR Volume property's range (or a Skip Block that is not a power
 * of two) is replaced in the property by the nearest valid one as soon as it is set, with a
 * status-bar message: the panel never holds a value the engine refuses.
 *
 * State in the panel: information properties are not refreshed by ParaView after a render, so
 * the behaviour pulls the INR Volume representations' information properties (Refinement State,
 * Accumulated Frames, Convergence Estimate, Backend In Use, ...) a moment after renders (at most
 * about four times a second while refining, and once after the last render), and shows the
 * refinement state in the main window's status bar while it refines.
 *
 * Measurement: with the environment variable INR_VOLUME_EVENT_LOOP_LOG set to a file name, a
 * precise 5 ms timer watches the Qt event loop and appends one line per stall longer than 40 ms
 * ("block_ms=<ms> end=<seconds of CLOCK_MONOTONIC>"): how long the GUI could not answer the user,
 * whatever held it (a render, Apply's pipeline update, a panel rebuild). The GUI tests read it.
 */
#ifndef pqInrRefinementBehavior_h
#define pqInrRefinementBehavior_h

#include <QElapsedTimer>
#include <cstdio>
#include <QObject>
#include <QPointer>
#include <QSet>
#include <QTimer>

class pqDataRepresentation;
class pqRepresentation;
class pqView;
class vtkObject;
class pqPipelineSource;

class pqInrRefinementBehavior : public QObject
{
  Q_OBJECT
public:
  pqInrRefinementBehavior(QObject* parent = nullptr);
  ~pqInrRefinementBehavior() override;

  void onStartup();
  void onShutdown();

private Q_SLOTS:
  void onViewAdded(pqView* view);
  void onRepresentationAdded(pqRepresentation* repr);
  void onRepresentationTypeChanged();
  void onSettingModified(vtkObject* caller);
  void onEndRender();
  void onInteraction(vtkObject* interactor, unsigned long event);
  void refine();
  void refreshState();
  void watchEventLoop();

private:
  bool colorByModel(pqDataRepresentation* repr);

private:
  QTimer Timer;
  QTimer StateTimer;  // refreshState after renders
  QElapsedTimer SinceRender;  // since the last render of a view (interaction settling)
  QList<QPointer<pqView>> Pending;
  QSet<void*> AutoColored;
  QSet<vtkObject*> Interacting;  // view interactors between Start- and EndInteractionEvent
  bool FixingSetting = false;
  QTimer EventLoopWatch;       // INR_VOLUME_EVENT_LOOP_LOG
  QElapsedTimer SinceWatch;    // since the watch's last tick
  FILE* EventLoopLog = nullptr;
};

#endif
