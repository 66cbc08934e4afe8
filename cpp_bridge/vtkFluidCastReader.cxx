#include "vtkFluidCastReader.h"

#include "vtkAppendPolyData.h"
#include "vtkCellArray.h"
#include "vtkDataArray.h"
#include "vtkDoubleArray.h"
#include "vtkErrorCode.h"
#include "vtkFieldData.h"
#include "vtkIdTypeArray.h"
#include "vtkInformation.h"
#include "vtkInformationVector.h"
#include "vtkNew.h"
#include "vtkObjectFactory.h"
#include "vtkPointData.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkSetGet.h"
#include "vtkSmartPointer.h"
#include "vtkStreamingDemandDrivenPipeline.h"

#include "rust/cxx.h"
#include "fluidcast-cxx/src/lib.rs.h"

#include <algorithm>
#include <cctype>
#include <future>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

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
  // The arrays are contiguous (array-of-structs) buffers of the file's type.
  switch (a->GetDataType())
  {
    vtkTemplateMacro(std::transform(values.begin(), values.end(),
      static_cast<VTK_TT*>(a->GetVoidPointer(0)),
      [](double v) { return static_cast<VTK_TT>(v); }));
  }
  return a;
}

/// One vertex per particle, so that ParaView's Points and Surface representations show them.
vtkSmartPointer<vtkCellArray> Vertices(vtkIdType n)
{
  vtkNew<vtkIdTypeArray> offsets;
  vtkNew<vtkIdTypeArray> connectivity;
  offsets->SetNumberOfValues(n + 1);
  connectivity->SetNumberOfValues(n);
  for (vtkIdType i = 0; i < n; ++i)
  {
    offsets->SetValue(i, i);
    connectivity->SetValue(i, i);
  }
  offsets->SetValue(n, n);
  auto verts = vtkSmartPointer<vtkCellArray>::New();
  verts->SetData(offsets, connectivity);
  return verts;
}

/// Reads one particle file into a new vtkPolyData; throws rust::Error naming the file and
/// the problem.
vtkSmartPointer<vtkPolyData> ReadFile(const std::string& path)
{
  rust::Box<fluidcast::ParticleFile> f = fluidcast::read_particle_file(path);
  auto output = vtkSmartPointer<vtkPolyData>::New();
  const auto xyz = f->points();
  const vtkIdType n = static_cast<vtkIdType>(xyz.size() / 3);
  vtkNew<vtkDoubleArray> coords;
  coords->SetNumberOfComponents(3);
  coords->SetNumberOfTuples(n);
  std::copy(xyz.begin(), xyz.end(), coords->GetPointer(0));
  vtkNew<vtkPoints> points;
  points->SetData(coords);
  output->SetPoints(points);
  output->SetVerts(Vertices(n));
  for (size_t i = 0; i < f->array_count(false); ++i)
  {
    output->GetPointData()->AddArray(MakeArray(*f, false, i));
  }
  for (size_t i = 0; i < f->array_count(true); ++i)
  {
    output->GetFieldData()->AddArray(MakeArray(*f, true, i));
  }
  return output;
}

/// Computes what ParaView's data information asks of every new data set (bounds, and each
/// array's range and finite range per component and of the magnitude), so that it is cached in
/// the arrays (VTK keeps ranges until an array is modified). On the prefetch thread this takes
/// that work off the main thread: for 2.7M particles with 8 arrays it is about 2 s of the
/// data information ParaView gathers for each time step.
void CacheRanges(vtkPolyData* data)
{
  double bounds[6];
  data->GetBounds(bounds);
  auto cache = [](vtkDataArray* a)
  {
    for (int c = -1; c < a->GetNumberOfComponents(); ++c)
    {
      double range[2];
      a->GetRange(range, c);
      a->GetFiniteRange(range, c);
    }
  };
  cache(data->GetPoints()->GetData());
  for (int i = 0; i < data->GetPointData()->GetNumberOfArrays(); ++i)
  {
    if (vtkDataArray* a = data->GetPointData()->GetArray(i))
    {
      cache(a);
    }
  }
}

/// A time step read (or the error that stopped it, naming the file and the problem).
struct Frame
{
  vtkSmartPointer<vtkPolyData> Data;
  std::string Error;
};

/// The particles of `files` (the parts of one time step, appended in order), with their
/// ranges cached when `cacheRanges`. Runs on the prefetch thread too: it touches nothing but
/// its own objects and reports no VTK error.
Frame ReadStep(const std::vector<std::string>& files, bool cacheRanges)
{
  Frame frame;
  try
  {
    if (files.size() == 1)
    {
      frame.Data = ReadFile(files.front());
    }
    else
    {
      vtkNew<vtkAppendPolyData> append;
      for (const auto& file : files)
      {
        append->AddInputData(ReadFile(file));
      }
      append->Update();
      frame.Data = append->GetOutput();
    }
    if (cacheRanges)
    {
      CacheRanges(frame.Data);
    }
  }
  catch (const rust::Error& e)
  {
    frame.Error = e.what();
  }
  catch (const std::exception& e)
  {
    frame.Error = e.what();
  }
  return frame;
}

bool HasExtension(const std::string& name, const char* ext)
{
  const auto dot = name.rfind('.');
  if (dot == std::string::npos)
  {
    return false;
  }
  std::string e = name.substr(dot + 1);
  std::transform(e.begin(), e.end(), e.begin(),
    [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e == ext;
}
}

/// The .pvd series of FileName and the time step the prefetch thread is reading.
struct vtkFluidCastReader::vtkInternals
{
  /// One distinct time of the series with the files of its parts.
  struct Step
  {
    double Time;
    std::vector<std::string> Files;
  };
  /// The .pvd the steps were read from ("" when FileName is a single file).
  std::string SeriesFile;
  std::vector<Step> Steps;
  /// The files the prefetch thread reads (empty: none), and its result.
  std::vector<std::string> PendingFiles;
  std::future<Frame> Pending;

  /// Reads the series' steps (throws rust::Error naming the .pvd and the problem).
  void ReadSeries(const std::string& pvd)
  {
    this->Steps.clear();
    this->SeriesFile.clear();
    for (const auto& step : fluidcast::read_series(pvd))
    {
      Step s{ step.time, {} };
      for (const auto& file : step.files)
      {
        s.Files.emplace_back(std::string(file));
      }
      this->Steps.push_back(std::move(s));
    }
    this->SeriesFile = pvd;
  }

  /// The step for time `t`: the last at or before it, the first for a time before them all.
  size_t StepAt(double t) const
  {
    const auto after = std::upper_bound(this->Steps.begin(), this->Steps.end(), t,
      [](double time, const Step& s) { return time < s.Time; });
    return after == this->Steps.begin() ? 0 : static_cast<size_t>(after - this->Steps.begin() - 1);
  }

  /// The frame of step `i`: the prefetched one when it is that step (`prefetched` set), else
  /// read now.
  Frame Take(size_t i, bool& prefetched)
  {
    prefetched = this->Pending.valid() && this->PendingFiles == this->Steps[i].Files;
    if (prefetched)
    {
      this->PendingFiles.clear();
      return this->Pending.get();
    }
    return ReadStep(this->Steps[i].Files, false);
  }

  /// Starts reading step `i` on the prefetch thread (waiting for one still running).
  void Prefetch(size_t i)
  {
    if (i >= this->Steps.size() || (this->Pending.valid() && this->PendingFiles == this->Steps[i].Files))
    {
      return;
    }
    this->Drop();
    this->PendingFiles = this->Steps[i].Files;
    this->Pending = std::async(std::launch::async, ReadStep, this->PendingFiles, true);
  }

  /// Forgets the prefetched step (after the thread has finished with it).
  void Drop()
  {
    if (this->Pending.valid())
    {
      this->Pending.wait();
      this->Pending = std::future<Frame>();
    }
    this->PendingFiles.clear();
  }
};

vtkFluidCastReader::vtkFluidCastReader()
  : Internals(new vtkInternals)
{
  this->SetNumberOfInputPorts(0);
}

vtkFluidCastReader::~vtkFluidCastReader()
{
  this->Internals->Drop();
  this->SetFileName(nullptr);
}

int vtkFluidCastReader::CanReadFile(const char* fname)
{
  // A .vtu, .vtp, .vtk or .pvd of particles only (fluidcast-cxx decides, extensions and
  // all): a mesh (cells other than vertices, cell data) or a structured grid is left to
  // VTK's and ParaView's own readers, which keep what this reader would drop.
  try
  {
    return fname && fluidcast::particle_reader_claims(fname) ? 1 : 0;
  }
  catch (const std::exception&)
  {
    return 0; // a file name that is not UTF-8 (rust::Str refuses it): not ours to read
  }
}

int vtkFluidCastReader::GetNumberOfTimeSteps() const
{
  return static_cast<int>(this->Internals->Steps.size());
}

int vtkFluidCastReader::RequestInformation(
  vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  this->SetErrorCode(vtkErrorCode::NoError);
  vtkInformation* outInfo = outputVector->GetInformationObject(0);
  outInfo->Remove(vtkStreamingDemandDrivenPipeline::TIME_STEPS());
  outInfo->Remove(vtkStreamingDemandDrivenPipeline::TIME_RANGE());
  auto& internals = *this->Internals;
  const std::string name = this->FileName ? this->FileName : "";
  if (!HasExtension(name, "pvd"))
  {
    internals.Drop();
    internals.Steps.clear();
    internals.SeriesFile.clear();
    return 1;
  }
  try
  {
    auto before = internals.Steps;
    internals.ReadSeries(name);
    const bool same = before.size() == internals.Steps.size() &&
      std::equal(before.begin(), before.end(), internals.Steps.begin(),
        [](const vtkInternals::Step& a, const vtkInternals::Step& b)
        { return a.Time == b.Time && a.Files == b.Files; });
    if (!same)
    {
      internals.Drop();
    }
  }
  catch (const rust::Error& e)
  {
    // The request fails (the .pvd itself is unreadable: no time steps to offer).
    vtkErrorMacro(<< e.what());
    this->SetErrorCode(vtkErrorCode::FileFormatError);
    internals.Drop();
    internals.Steps.clear();
    return 0;
  }
  std::vector<double> times;
  for (const auto& step : internals.Steps)
  {
    times.push_back(step.Time);
  }
  outInfo->Set(vtkStreamingDemandDrivenPipeline::TIME_STEPS(), times.data(),
    static_cast<int>(times.size()));
  const double range[2] = { times.front(), times.back() };
  outInfo->Set(vtkStreamingDemandDrivenPipeline::TIME_RANGE(), range, 2);
  return 1;
}

int vtkFluidCastReader::RequestData(
  vtkInformation*, vtkInformationVector**, vtkInformationVector* outputVector)
{
  vtkInformation* outInfo = outputVector->GetInformationObject(0);
  vtkPolyData* output = vtkPolyData::GetData(outputVector);
  this->SetErrorCode(vtkErrorCode::NoError);
  if (!this->FileName || !*this->FileName)
  {
    vtkErrorMacro(<< "no FileName set");
    this->SetErrorCode(vtkErrorCode::NoFileNameError);
    return 1;
  }
  auto& internals = *this->Internals;
  Frame frame;
  double time = 0.0;
  if (internals.Steps.empty())
  {
    frame = ReadStep({ this->FileName }, false);
  }
  else
  {
    const double t = outInfo->Has(vtkStreamingDemandDrivenPipeline::UPDATE_TIME_STEP())
      ? outInfo->Get(vtkStreamingDemandDrivenPipeline::UPDATE_TIME_STEP())
      : internals.Steps.front().Time;
    const size_t i = internals.StepAt(t);
    bool prefetched = false;
    frame = internals.Take(i, prefetched);
    this->PrefetchedSteps += prefetched ? 1 : 0;
    if (this->Prefetch)
    {
      internals.Prefetch(i + 1);
    }
    else
    {
      internals.Drop();
    }
    if (!frame.Error.empty())
    {
      std::ostringstream where;
      where << internals.SeriesFile << ", time step " << i << " (t = " << internals.Steps[i].Time
            << "): " << frame.Error;
      frame.Error = where.str();
    }
    time = internals.Steps[i].Time;
  }
  if (!frame.Error.empty())
  {
    // Reported once, here; the output stays empty and GetErrorCode() says the read failed
    // (as VTK's own readers do, without failing the pipeline request).
    vtkErrorMacro(<< frame.Error);
    this->SetErrorCode(vtkErrorCode::FileFormatError);
    output->Initialize();
  }
  else
  {
    output->ShallowCopy(frame.Data);
  }
  if (!internals.Steps.empty())
  {
    output->GetInformation()->Set(vtkDataObject::DATA_TIME_STEP(), time);
  }
  return 1;
}

void vtkFluidCastReader::PrintSelf(ostream& os, vtkIndent indent)
{
  this->Superclass::PrintSelf(os, indent);
  os << indent << "FileName: " << (this->FileName ? this->FileName : "(none)") << "\n";
  os << indent << "Prefetch: " << this->Prefetch << "\n";
  os << indent << "PrefetchedSteps: " << this->PrefetchedSteps << "\n";
  os << indent << "NumberOfTimeSteps: " << this->GetNumberOfTimeSteps() << "\n";
}
