#include "vtkFluidCastReader.h"

#include "vtkCellArray.h"
#include "vtkDataArray.h"
#include "vtkDoubleArray.h"
#include "vtkErrorCode.h"
#include "vtkFieldData.h"
#include "vtkIdTypeArray.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkObjectFactory.h"
#include "vtkPointData.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkSmartPointer.h"

#include "rust/cxx.h"
#include "fluidcast-cxx/src/lib.rs.h"

#include <algorithm>
#include <cctype>
#include <string>

vtkStandardNewMacro(vtkFluidCastReader);

namespace
{
/// The VTK type for a VTK XML type name (as fluidcast reports it).
int VTKType(const std::string& name)
{
  if (name == "Int8")
    return VTK_SIGNED_CHAR;
  if (name == "UInt8")
    return VTK_UNSIGNED_CHAR;
  if (name == "Int16")
    return VTK_SHORT;
  if (name == "UInt16")
    return VTK_UNSIGNED_SHORT;
  if (name == "Int32")
    return VTK_INT;
  if (name == "UInt32")
    return VTK_UNSIGNED_INT;
  if (name == "Int64")
    return VTK_LONG_LONG;
  if (name == "UInt64")
    return VTK_UNSIGNED_LONG_LONG;
  if (name == "Float32")
    return VTK_FLOAT;
  return VTK_DOUBLE;
}

/// Array `i` of the file's point data (`field` false) or field data as a vtkDataArray.
vtkSmartPointer<vtkDataArray> MakeArray(const fluidcast::ParticleFile& f, bool field, size_t i)
{
  auto a = vtkSmartPointer<vtkDataArray>::Take(
    vtkDataArray::CreateDataArray(VTKType(std::string(f.array_type(field, i)))));
  const auto nc = static_cast<int>(f.array_components(field, i));
  const auto values = f.array_values(field, i);
  a->SetName(std::string(f.array_name(field, i)).c_str());
  a->SetNumberOfComponents(nc);
  a->SetNumberOfTuples(static_cast<vtkIdType>(values.size() / static_cast<size_t>(nc)));
  for (size_t k = 0; k < values.size(); ++k)
  {
    a->SetComponent(static_cast<vtkIdType>(k / nc), static_cast<int>(k % nc), values[k]);
  }
  return a;
}
}

vtkFluidCastReader::vtkFluidCastReader()
{
  this->SetNumberOfInputPorts(0);
}

vtkFluidCastReader::~vtkFluidCastReader()
{
  this->SetFileName(nullptr);
}

int vtkFluidCastReader::CanReadFile(const char* fname)
{
  if (!fname)
  {
    return 0;
  }
  std::string s(fname);
  const auto dot = s.rfind('.');
  if (dot == std::string::npos)
  {
    return 0;
  }
  std::string ext = s.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(),
    [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == "vtu" || ext == "vtp" || ext == "vtk" ? 1 : 0;
}

int vtkFluidCastReader::RequestData(
  vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  vtkPolyData* output = vtkPolyData::GetData(outputVector);
  this->SetErrorCode(vtkErrorCode::NoError);
  if (!this->FileName || !*this->FileName)
  {
    vtkErrorMacro(<< "no FileName set");
    this->SetErrorCode(vtkErrorCode::NoFileNameError);
    return 1;
  }
  try
  {
    rust::Box<fluidcast::ParticleFile> f = fluidcast::read_particle_file(this->FileName);
    const auto xyz = f->points();
    const vtkIdType n = static_cast<vtkIdType>(xyz.size() / 3);
    vtkNew<vtkDoubleArray> coords;
    coords->SetNumberOfComponents(3);
    coords->SetNumberOfTuples(n);
    std::copy(xyz.begin(), xyz.end(), coords->GetPointer(0));
    vtkNew<vtkPoints> points;
    points->SetData(coords);
    output->SetPoints(points);
    // One vertex per particle, so that ParaView's Points and Surface representations show
    // them too.
    vtkNew<vtkIdTypeArray> offsets;
    vtkNew<vtkIdTypeArray> connectivity;
    offsets->SetNumberOfValues(n + 1);
    connectivity->SetNumberOfValues(n);
    for (vtkIdType i = 0; i <= n; ++i)
    {
      offsets->SetValue(i, i);
      if (i < n)
      {
        connectivity->SetValue(i, i);
      }
    }
    vtkNew<vtkCellArray> verts;
    verts->SetData(offsets, connectivity);
    output->SetVerts(verts);
    for (size_t i = 0; i < f->array_count(false); ++i)
    {
      output->GetPointData()->AddArray(MakeArray(*f, false, i));
    }
    for (size_t i = 0; i < f->array_count(true); ++i)
    {
      output->GetFieldData()->AddArray(MakeArray(*f, true, i));
    }
  }
  catch (const rust::Error& e)
  {
    // Reported once, here; the output stays empty and GetErrorCode() says the read failed
    // (as VTK's own readers do, without failing the pipeline request).
    vtkErrorMacro(<< e.what());
    this->SetErrorCode(vtkErrorCode::FileFormatError);
    output->Initialize();
  }
  return 1;
}

void vtkFluidCastReader::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "FileName: " << (this->FileName ? this->FileName : "(none)") << "\n";
}
