#include "vtkFluidCastRepresentation.h"

#include "fluidcastDistribute.h"
#include "vtkCamera.h"
#include "vtkColorTransferFunction.h"
#include "vtkCommunicator.h"
#include "vtkDataObject.h"
#include "vtkFluidCastVolumeMapper.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkMath.h"
#include "vtkMultiProcessController.h"
#include "vtkObjectFactory.h"
#include "vtkPVLODVolume.h"
#include "vtkPVRenderView.h"
#include "vtkPointSet.h"
#include "vtkPolyData.h"
#include "vtkRenderer.h"
#include "vtkScalarsToColors.h"
#include "vtkSmartVolumeMapper.h"
#include "vtkContourValues.h"
#include "vtkVolumeMapper.h"
#include "vtkVolumeProperty.h"

#include <cstring>
#include <limits>

vtkStandardNewMacro(vtkFluidCastRepresentation);

//------------------------------------------------------------------------------
vtkFluidCastRepresentation::vtkFluidCastRepresentation()
{
  this->Actor->SetMapper(this->Mapper);
  this->Actor->SetProperty(this->Property);
  this->Actor->SetEnableLOD(0);
  vtkMath::UninitializeBounds(this->DataBounds);
}

//------------------------------------------------------------------------------
vtkFluidCastRepresentation::~vtkFluidCastRepresentation() = default;

//------------------------------------------------------------------------------
int vtkFluidCastRepresentation::FillInputPortInformation(int, vtkInformation* info)
{
  info->Set(vtkAlgorithm::INPUT_REQUIRED_DATA_TYPE(), "vtkPointSet");
  info->Set(vtkAlgorithm::INPUT_IS_OPTIONAL(), 1);
  return 1;
}

//------------------------------------------------------------------------------
int vtkFluidCastRepresentation::RequestData(
  vtkInformation* request, vtkInformationVector** inputVector, vtkInformationVector* outputVector)
{
  vtkMath::UninitializeBounds(this->DataBounds);
  this->Cache = nullptr;
  this->Distributed = false;
  this->OwnedParticles = this->HaloParticles = 0;
  vtkMultiProcessController* controller = vtkMultiProcessController::GetGlobalController();
  vtkPointSet* input = inputVector[0]->GetNumberOfInformationObjects() == 1
    ? vtkPointSet::GetData(inputVector[0], 0)
    : nullptr;
  if (controller && controller->GetNumberOfProcesses() > 1)
  {
    // Collective: every rank's representation updates together.
    this->UpdateMapperParameters();
    fluidcast_paraview::Partition part =
      fluidcast_paraview::Distribute(input, this->Mapper, controller);
    this->Cache = part.Particles;
    this->Distributed = part.Region.IsValid();
    this->OwnedParticles = part.Owned;
    this->HaloParticles = part.Halo;
    if (this->Distributed)
    {
      part.Region.GetBounds(this->Region);
      part.Region.GetBounds(this->DataBounds);
      fluidcast_paraview::CroppingPlanes(part.Region, part.Extent, this->CroppingPlanes);
    }
    vtkDebugMacro(<< "rank " << controller->GetLocalProcessId() << ": " << part.Owned
                  << " particles owned, " << part.Halo << " halo, support radius "
                  << part.SupportRadius << " from " << part.RadiusNote);
  }
  else if (input)
  {
    this->Cache.TakeReference(input->NewInstance());
    this->Cache->ShallowCopy(input);
    // The field reaches one support radius beyond the particles: let the mapper tell.
    this->Mapper->SetInputData(fluidcast_paraview::WithoutHalo(this->Cache));
    this->UpdateMapperParameters();
    this->Mapper->GetBounds(this->DataBounds);
  }
  if (!this->Cache)
  {
    this->Cache = vtkSmartPointer<vtkPolyData>::New();
  }
  return this->Superclass::RequestData(request, inputVector, outputVector);
}

//------------------------------------------------------------------------------
int vtkFluidCastRepresentation::ProcessViewRequest(
  vtkInformationRequestKey* request_type, vtkInformation* inInfo, vtkInformation* outInfo)
{
  if (!this->Superclass::ProcessViewRequest(request_type, inInfo, outInfo))
  {
    return 0;
  }
  if (request_type == vtkPVView::REQUEST_UPDATE())
  {
    // Ordered compositing by the boxes the ranks own (in parallel; one box otherwise): the
    // view orders the ranks' images by these bounds and moves no particle itself.
    outInfo->Set(vtkPVRenderView::NEED_ORDERED_COMPOSITING(), 1);
    vtkPVRenderView::SetPiece(inInfo, this, this->Cache);
    vtkPVRenderView::SetGeometryBounds(inInfo, this, this->DataBounds);
    vtkPVRenderView::SetOrderedCompositingConfiguration(
      inInfo, this, vtkPVRenderView::USE_BOUNDS_FOR_REDISTRIBUTION, this->DataBounds);
  }
  else if (request_type == vtkPVView::REQUEST_RENDER())
  {
    vtkPointSet* data = vtkPointSet::SafeDownCast(vtkPVView::GetDeliveredPiece(inInfo, this));
    if (this->Distributed)
    {
      // This rank's own particles and halo: render the field inside its box only, with the
      // same rays and depth samples as every other rank.
      this->Mapper->SetCroppingRegionPlanes(this->CroppingPlanes);
      this->Mapper->SetCropping(1);
      this->Mapper->SetInputData(data);
      this->UpdateMapperParameters();
      this->ShareSupportDepths(vtkPVRenderView::SafeDownCast(this->GetView()));
      return 1;
    }
    // One process, or every rank's piece gathered here: halo copies would count twice.
    this->Mapper->SetCropping(0);
    this->Mapper->ClearSharedSupportDepthRange();
    if (data != this->GatheredFrom || (data && data->GetMTime() > this->GatheredTime))
    {
      this->Gathered = fluidcast_paraview::WithoutHalo(data);
      this->GatheredFrom = data;
      this->GatheredTime.Modified();
    }
    this->Mapper->SetInputData(this->Gathered);
    this->UpdateMapperParameters();
  }
  return 1;
}

//------------------------------------------------------------------------------
void vtkFluidCastRepresentation::ShareSupportDepths(vtkPVRenderView* view)
{
  // Collective: REQUEST_RENDER reaches every rank's representation in each parallel render
  // (the mapper's Render may not: a renderer culls a volume whose box is out of view).
  const double inf = std::numeric_limits<double>::infinity();
  double local[2] = { inf, inf }, all[2], range[2];
  vtkCamera* cam = view ? view->GetActiveCamera() : nullptr;
  if (this->Mapper->ComputeSupportDepthRange(cam, range))
  {
    local[0] = range[0];
    local[1] = -range[1];
  }
  vtkMultiProcessController::GetGlobalController()->AllReduce(
    local, all, 2, vtkCommunicator::MIN_OP);
  if (all[0] <= -all[1])
  {
    this->Mapper->SetSharedSupportDepthRange(all[0], -all[1]);
  }
  else
  {
    this->Mapper->ClearSharedSupportDepthRange();
  }
}

//------------------------------------------------------------------------------
void vtkFluidCastRepresentation::UpdateMapperParameters()
{
  const char* name = nullptr;
  vtkInformation* info = this->GetInputArrayInformation(0);
  if (info && info->Has(vtkDataObject::FIELD_NAME()))
  {
    name = info->Get(vtkDataObject::FIELD_NAME());
  }
  this->Mapper->SelectScalarArray(name);
  this->Mapper->SetScalarMode(VTK_SCALAR_MODE_USE_POINT_FIELD_DATA);
  // In parallel every rank must cast the same rays: no per-rank adjustment to its own timing.
  this->Mapper->SetAutoAdjustSampleDistances(this->Distributed ? 0 : this->AutoAdjust);
  // Vectors: the colour map's vector mode (ParaView's "Magnitude" / "X" / "Y" / "Z").
  if (vtkColorTransferFunction* ctf = this->Property->GetRGBTransferFunction(0))
  {
    if (ctf->GetVectorMode() == vtkScalarsToColors::COMPONENT)
    {
      this->Mapper->SetVectorMode(vtkSmartVolumeMapper::COMPONENT);
      this->Mapper->SetVectorComponent(ctf->GetVectorComponent());
    }
    else
    {
      this->Mapper->SetVectorMode(vtkSmartVolumeMapper::MAGNITUDE);
    }
  }
  this->Actor->SetMapper(this->Mapper);
}

//------------------------------------------------------------------------------
bool vtkFluidCastRepresentation::AddToView(vtkView* view)
{
  if (vtkPVRenderView* rview = vtkPVRenderView::SafeDownCast(view))
  {
    rview->GetRenderer()->AddActor(this->Actor);
    return this->Superclass::AddToView(view);
  }
  return false;
}

//------------------------------------------------------------------------------
bool vtkFluidCastRepresentation::RemoveFromView(vtkView* view)
{
  if (vtkPVRenderView* rview = vtkPVRenderView::SafeDownCast(view))
  {
    rview->GetRenderer()->RemoveActor(this->Actor);
    return this->Superclass::RemoveFromView(view);
  }
  return false;
}

//------------------------------------------------------------------------------
void vtkFluidCastRepresentation::SetSupportRadius(double h)
{
  this->Mapper->SetSupportRadius(h);
  this->MarkModified();
}

void vtkFluidCastRepresentation::SetRadiusArray(const char* name)
{
  const bool none = !name || !name[0] || std::strcmp(name, "None") == 0;
  this->Mapper->SetRadiusArray(none ? nullptr : name);
  this->MarkModified();
}

void vtkFluidCastRepresentation::SetRadiusScale(double s)
{
  this->Mapper->SetRadiusScale(s);
  this->MarkModified();
}

void vtkFluidCastRepresentation::SetKernel(int kernel)
{
  const std::string name = vtkFluidCastVolumeMapper::GetKernelName(kernel);
  if (name.empty())
  {
    vtkErrorMacro(<< "unknown kernel " << kernel);
    return;
  }
  this->Mapper->SetKernel(name.c_str());
}

void vtkFluidCastRepresentation::SetNumberOfIsosurfaces(int n)
{
  this->Property->GetIsoSurfaceValues()->SetNumberOfContours(n);
  this->Mapper->SetBlendMode(
    n > 0 ? vtkVolumeMapper::ISOSURFACE_BLEND : vtkVolumeMapper::COMPOSITE_BLEND);
}

void vtkFluidCastRepresentation::SetIsosurfaceValue(int i, double value)
{
  const std::string why = vtkFluidCastVolumeMapper::CheckSetting("IsoValue", value);
  if (!why.empty())
  {
    vtkErrorMacro(<< "FluidCastIsosurfaceValues[" << i << "]: " << why);
    return;
  }
  this->Property->GetIsoSurfaceValues()->SetValue(i, value);
  this->Mapper->SetBlendMode(vtkVolumeMapper::ISOSURFACE_BLEND);
}

void vtkFluidCastRepresentation::SetIsosurfaceField(const char* name)
{
  this->Mapper->SetIsoSurfaceField(name && name[0] ? name : "colour");
}

void vtkFluidCastRepresentation::SetIsosurfaceOpacity(double opacity)
{
  this->Mapper->SetIsoSurfaceOpacity(opacity);
}

void vtkFluidCastRepresentation::SetIsosurfaceWithVolume(int on)
{
  this->Mapper->SetIsoSurfaceWithVolume(on);
}

void vtkFluidCastRepresentation::SetShade(int on)
{
  this->Property->SetShade(on);
}

void vtkFluidCastRepresentation::SetAmbient(double v)
{
  this->Property->SetAmbient(v);
}

void vtkFluidCastRepresentation::SetDiffuse(double v)
{
  this->Property->SetDiffuse(v);
}

void vtkFluidCastRepresentation::SetSpecular(double v)
{
  this->Property->SetSpecular(v);
}

void vtkFluidCastRepresentation::SetSpecularPower(double v)
{
  this->Property->SetSpecularPower(v);
}

void vtkFluidCastRepresentation::SetErrorTolerance(double e)
{
  this->Mapper->SetErrorTolerance(e);
}

void vtkFluidCastRepresentation::SetMemoryLimit(double mib)
{
  this->Mapper->SetMemoryLimit(mib);
}

void vtkFluidCastRepresentation::SetWorkLimit(double evaluations)
{
  this->Mapper->SetWorkLimit(evaluations);
}

void vtkFluidCastRepresentation::SetLODTolerance(double px)
{
  this->Mapper->SetLODTolerance(px);
}

void vtkFluidCastRepresentation::SetField(int field)
{
  // The names and their order come from the Rust side (the bridge's field_names()); one
  // past the list is the first.
  std::string name = vtkFluidCastVolumeMapper::GetFieldName(field);
  this->Mapper->SetField(
    name.empty() ? vtkFluidCastVolumeMapper::GetFieldName(0).c_str() : name.c_str());
}

void vtkFluidCastRepresentation::SetRBFClassification(int classification)
{
  std::string name = vtkFluidCastVolumeMapper::GetRBFClassificationName(classification);
  this->Mapper->SetRBFClassification(
    name.empty() ? vtkFluidCastVolumeMapper::GetRBFClassificationName(0).c_str() : name.c_str());
}

void vtkFluidCastRepresentation::SetRBFRadius(double r)
{
  this->Mapper->SetRBFRadius(r);
}

void vtkFluidCastRepresentation::SetSamplesPerPixel(int n)
{
  this->Mapper->SetSamplesPerPixel(n);
}

void vtkFluidCastRepresentation::SetProgressivePasses(int n)
{
  this->Mapper->SetProgressivePasses(n);
}

void vtkFluidCastRepresentation::SetShadows(int on)
{
  this->Mapper->SetShadows(on);
}

void vtkFluidCastRepresentation::SetLightDirection(double x, double y, double z)
{
  this->Mapper->SetLightDirection(x, y, z);
}

void vtkFluidCastRepresentation::SetShadowAmbient(double a)
{
  this->Mapper->SetShadowAmbient(a);
}

void vtkFluidCastRepresentation::AddRBFRadiusMapPoint(double position, double factor)
{
  this->Mapper->AddRBFRadiusMapPoint(position, factor);
}

void vtkFluidCastRepresentation::RemoveAllRBFRadiusMapPoints()
{
  this->Mapper->RemoveAllRBFRadiusMapPoints();
}

void vtkFluidCastRepresentation::SetBackend(int backend)
{
  this->Mapper->SetBackend(backend);
}

void vtkFluidCastRepresentation::SetMode(int mode)
{
  // The names and their order come from the Rust side (fluidcast_backend::Mode::NAMES).
  std::string name = vtkFluidCastVolumeMapper::GetModeName(mode);
  this->Mapper->SetMode(name.empty() ? "auto" : name.c_str());
}

void vtkFluidCastRepresentation::SetGridCell(int px)
{
  this->Mapper->SetGridCell(px);
}

void vtkFluidCastRepresentation::SetProbe(int on)
{
  this->Mapper->SetProbe(on);
}

void vtkFluidCastRepresentation::SetSuperPixels(int on)
{
  this->Mapper->SetSuperPixels(on);
}

void vtkFluidCastRepresentation::SetSurfaceCells(int on)
{
  this->Mapper->SetSurfaceCells(on);
}

void vtkFluidCastRepresentation::SetInterpolation(int on)
{
  this->Mapper->SetInterpolation(on);
}

void vtkFluidCastRepresentation::SetTiles(int tiles)
{
  this->Mapper->SetTiles(tiles);
}

void vtkFluidCastRepresentation::SetRelax(double v)
{
  this->Mapper->SetRelax(v);
}

void vtkFluidCastRepresentation::SetStrict(int v)
{
  this->Mapper->SetStrict(v);
}

void vtkFluidCastRepresentation::SetBundleSize(int v)
{
  this->Mapper->SetBundleSize(v);
}

void vtkFluidCastRepresentation::SetDepthSamples(int v)
{
  this->Mapper->SetDepthSamples(v);
}

void vtkFluidCastRepresentation::SetSamplingScale(double v)
{
  this->Mapper->SetSamplingScale(v);
}

void vtkFluidCastRepresentation::SetOcclusionCulling(int v)
{
  this->Mapper->SetOcclusionCulling(v);
}

void vtkFluidCastRepresentation::SetRBFSeed(int v)
{
  this->Mapper->SetRBFSeed(v);
}

void vtkFluidCastRepresentation::SetRBFLeafSize(int v)
{
  this->Mapper->SetRBFLeafSize(v);
}

void vtkFluidCastRepresentation::SetRBFStep(double v)
{
  this->Mapper->SetRBFStep(v);
}

void vtkFluidCastRepresentation::SetShadowSamples(int v)
{
  this->Mapper->SetShadowSamples(v);
}

void vtkFluidCastRepresentation::SetShadeVolume(int on)
{
  this->Mapper->SetShadeVolume(on);
}

void vtkFluidCastRepresentation::SetRBFNoise(int noise)
{
  std::string name = vtkFluidCastVolumeMapper::GetRBFNoiseName(noise);
  this->Mapper->SetRBFNoise(
    name.empty() ? vtkFluidCastVolumeMapper::GetRBFNoiseName(0).c_str() : name.c_str());
}

void vtkFluidCastRepresentation::SetAdapter(const char* name)
{
  this->Mapper->SetAdapter(name && name[0] ? name : nullptr);
}

void vtkFluidCastRepresentation::SetAutoAdjustSampleDistances(int on)
{
  this->AutoAdjust = on;
  this->Mapper->SetAutoAdjustSampleDistances(this->Distributed ? 0 : on);
}

void vtkFluidCastRepresentation::SetImageSampleDistance(int s)
{
  this->Mapper->SetImageSampleDistance(s);
}

void vtkFluidCastRepresentation::SetMaximumImageSampleDistance(int s)
{
  this->Mapper->SetMaximumImageSampleDistance(s);
}

//------------------------------------------------------------------------------
const char* vtkFluidCastRepresentation::GetLastError()
{
  return this->Mapper->GetLastError();
}

const char* vtkFluidCastRepresentation::GetLastDevice()
{
  return this->Mapper->GetLastDevice();
}

vtkIdType vtkFluidCastRepresentation::GetLastTiles()
{
  return this->Mapper->GetLastTiles();
}

//------------------------------------------------------------------------------
void vtkFluidCastRepresentation::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "Distributed: " << this->Distributed << "\n";
  os << indent << "OwnedParticles: " << this->OwnedParticles << "\n";
  os << indent << "HaloParticles: " << this->HaloParticles << "\n";
  os << indent << "Mapper:\n";
  this->Mapper->PrintSelf(os, indent.GetNextIndent());
}
