#include "vtkPVFluidCastReader.h"

#include "vtkFluidCastReader.h"
#include "vtkExecutive.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkObjectFactory.h"
#include "vtkPolyData.h"
#include "vtkStreamingDemandDrivenPipeline.h"

vtkStandardNewMacro(vtkPVFluidCastReader);

vtkPVFluidCastReader::vtkPVFluidCastReader()
{
  this->SetNumberOfInputPorts(0);
}

vtkPVFluidCastReader::~vtkPVFluidCastReader()
{
  this->SetFileName(nullptr);
}

int vtkPVFluidCastReader::CanReadFile(const char* fname)
{
  return vtkFluidCastReader::CanReadFile(fname);
}

void vtkPVFluidCastReader::SetPrefetch(vtkTypeBool prefetch)
{
  if (this->Reader->GetPrefetch() != prefetch)
  {
    this->Reader->SetPrefetch(prefetch);
    this->Modified();
  }
}

vtkTypeBool vtkPVFluidCastReader::GetPrefetch()
{
  return this->Reader->GetPrefetch();
}

int vtkPVFluidCastReader::GetPrefetchedSteps()
{
  return this->Reader->GetPrefetchedSteps();
}

int vtkPVFluidCastReader::RequestInformation(
  vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  this->Reader->SetFileName(this->FileName);
  const int ok = this->Reader->GetExecutive()->UpdateInformation();
  vtkInformation* outInfo = outputVector->GetInformationObject(0);
  vtkInformation* theirs = this->Reader->GetOutputInformation(0);
  outInfo->CopyEntry(theirs, vtkStreamingDemandDrivenPipeline::TIME_STEPS());
  outInfo->CopyEntry(theirs, vtkStreamingDemandDrivenPipeline::TIME_RANGE());
  // An unreadable .pvd fails the information pass, as it fails the reader's own.
  return ok ? 1 : 0;
}

int vtkPVFluidCastReader::RequestData(
  vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  vtkInformation* outInfo = outputVector->GetInformationObject(0);
  // vtkFluidCastReader reports its own errors (vtkErrorMacro naming the file and the
  // problem); a failed read leaves the output empty and sets the error code.
  if (outInfo->Has(vtkStreamingDemandDrivenPipeline::UPDATE_TIME_STEP()))
  {
    this->Reader->UpdateTimeStep(outInfo->Get(vtkStreamingDemandDrivenPipeline::UPDATE_TIME_STEP()));
  }
  else
  {
    this->Reader->Update();
  }
  vtkPolyData* output = vtkPolyData::GetData(outputVector);
  vtkPolyData* theirs = this->Reader->GetOutput();
  output->ShallowCopy(theirs);
  vtkInformation* time = theirs->GetInformation();
  if (time->Has(vtkDataObject::DATA_TIME_STEP()))
  {
    output->GetInformation()->Set(
      vtkDataObject::DATA_TIME_STEP(), time->Get(vtkDataObject::DATA_TIME_STEP()));
  }
  this->SetErrorCode(this->Reader->GetErrorCode());
  return 1;
}

void vtkPVFluidCastReader::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "FileName: " << (this->FileName ? this->FileName : "(none)") << "\n";
  os << indent << "Reader:\n";
  this->Reader->PrintSelf(os, indent.GetNextIndent());
}
