#include "vtkPVFluidCastReader.h"

#include "vtkFluidCastReader.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkPolyData.h"

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

int vtkPVFluidCastReader::RequestData(
  vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  vtkNew<vtkFluidCastReader> reader;
  reader->SetFileName(this->FileName);
  // vtkFluidCastReader reports its own errors (vtkErrorMacro naming the file and the
  // problem); a failed read leaves the output empty and sets the error code.
  reader->Update();
  vtkPolyData* output = vtkPolyData::GetData(outputVector);
  output->ShallowCopy(reader->GetOutput());
  this->SetErrorCode(reader->GetErrorCode());
  return 1;
}

void vtkPVFluidCastReader::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "FileName: " << (this->FileName ? this->FileName : "(none)") << "\n";
}
