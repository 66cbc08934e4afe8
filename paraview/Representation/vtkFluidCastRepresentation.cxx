#include "vtkFluidCastRepresentation.h"

#include "vtkColorTransferFunction.h"
#include "vtkDataObject.h"
#include "vtkFluidCastVolumeMapper.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkMath.h"
#include "vtkObjectFactory.h"
#include "vtkPVLODVolume.h"
#include "vtkPVRenderView.h"
#include "vtkPointSet.h"
#include "vtkPolyData.h"
#include "vtkRenderer.h"
#include "vtkScalarsToColors.h"
#include "vtkSmartVolumeMapper.h"
#include "vtkVolumeProperty.h"

#include <cstring>

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
  if (inputVector[0]->GetNumberOfInformationObjects() == 1)
  {
    if (vtkPointSet* input = vtkPointSet::GetData(inputVector[0], 0))
    {
      this->Cache.TakeReference(input->NewInstance());
      this->Cache->ShallowCopy(input);
      // The field reaches one support radius beyond the particles: let the mapper tell.
      this->Mapper->SetInputData(this->Cache);
      this->UpdateMapperParameters();
      this->Mapper->GetBounds(this->DataBounds);
    }
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
    outInfo->Set(vtkPVRenderView::NEED_ORDERED_COMPOSITING(), 1);
    vtkPVRenderView::SetPiece(inInfo, this, this->Cache);
    vtkPVRenderView::SetGeometryBounds(inInfo, this, this->DataBounds);
  }
  else if (request_type == vtkPVView::REQUEST_RENDER())
  {
    vtkPointSet* data = vtkPointSet::SafeDownCast(vtkPVView::GetDeliveredPiece(inInfo, this));
    this->Mapper->SetInputData(data);
    this->UpdateMapperParameters();
  }
  return 1;
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

void vtkFluidCastRepresentation::SetErrorTolerance(double e)
{
  this->Mapper->SetErrorTolerance(e);
}

void vtkFluidCastRepresentation::SetBackend(int backend)
{
  this->Mapper->SetBackend(backend);
}

void vtkFluidCastRepresentation::SetAdapter(const char* name)
{
  this->Mapper->SetAdapter(name && name[0] ? name : nullptr);
}

void vtkFluidCastRepresentation::SetAutoAdjustSampleDistances(int on)
{
  this->Mapper->SetAutoAdjustSampleDistances(on);
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
void vtkFluidCastRepresentation::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "Mapper:\n";
  this->Mapper->PrintSelf(os, indent.GetNextIndent());
}
