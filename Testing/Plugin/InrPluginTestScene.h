// Scene pieces shared by the plugin's VTK-level tests (header-only, test code).
#ifndef InrPluginTestScene_h
#define InrPluginTestScene_h

#include "vtkActor.h"
#include "vtkColorTransferFunction.h"
#include "vtkNew.h"
#include "vtkPiecewiseFunction.h"
#include "vtkPolyDataMapper.h"
#include "vtkProperty.h"
#include "vtkRenderer.h"
#include "vtkSphereSource.h"

// The opaque sphere that cuts the test volume (Testing/Data/Plugin/clouds.inr, box [0,2]x[-1,1]x
// [0,1]): centred in the box, radius 0.42, so rays must stop at its depth.
inline void AddOpaqueSphere(vtkRenderer* ren)
{
  vtkNew<vtkSphereSource> sphere;
  sphere->SetCenter(1.0, 0.0, 0.5);
  sphere->SetRadius(0.42);
  sphere->SetThetaResolution(64);
  sphere->SetPhiResolution(32);
  vtkNew<vtkPolyDataMapper> mapper;
  mapper->SetInputConnection(sphere->GetOutputPort());
  vtkNew<vtkActor> actor;
  actor->SetMapper(mapper);
  actor->GetProperty()->SetColor(0.9, 0.75, 0.2);
  ren->AddActor(actor);
}

// The two-point colour and opacity ramps over the test volume's values [-0.14, 1.17] that the
// mapper-level tests without an image baseline use (blue to red, opaque from 0.55 up).
inline void SetTestRamps(vtkColorTransferFunction* ctf, vtkPiecewiseFunction* otf)
{
  ctf->AddRGBPoint(-0.14, 0.23, 0.30, 0.75);
  ctf->AddRGBPoint(1.17, 0.71, 0.02, 0.15);
  otf->AddPoint(0.55, 0.0);
  otf->AddPoint(1.17, 1.0);
}

#endif
