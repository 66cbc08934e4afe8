/**
 * @class   vtkPVFluidCastReader
 * @brief   ParaView's face of vtkFluidCastReader: the "fluidcast particle reader".
 *
 * A thin source over one vtkFluidCastReader (fluidcast's checked reader for .vtu, .vtp and
 * legacy .vtk particle files and .pvd time series) that passes its vtkPolyData on, with its
 * time steps, to ParaView's animation. It exists so that the reader is wrapped for
 * ParaView's server manager with the plugin; see vtkFluidCastReader for what it reads, how
 * it reads the next time step ahead (Prefetch) and how it reports damaged files (a VTK error,
 * never an abort).
 */
#ifndef vtkPVFluidCastReader_h
#define vtkPVFluidCastReader_h

#include "fluidcastParaViewRepresentationModule.h" // for export macro
#include "vtkNew.h"                             // for vtkNew
#include "vtkPolyDataAlgorithm.h"

class vtkFluidCastReader;

class FLUIDCASTPARAVIEWREPRESENTATION_EXPORT vtkPVFluidCastReader : public vtkPolyDataAlgorithm
{
public:
  static vtkPVFluidCastReader* New();
  vtkTypeMacro(vtkPVFluidCastReader, vtkPolyDataAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  ///@{
  /**
   * The file to read (.vtu, .vtp, .vtk or a .pvd time series).
   */
  vtkSetFilePathMacro(FileName);
  vtkGetFilePathMacro(FileName);
  ///@}

  ///@{
  /**
   * For a .pvd series: read the next time step on a second thread while the current one
   * renders (vtkFluidCastReader::Prefetch; default on).
   */
  void SetPrefetch(vtkTypeBool prefetch);
  vtkTypeBool GetPrefetch();
  vtkBooleanMacro(Prefetch, vtkTypeBool);
  ///@}

  /**
   * How many of the time steps output so far came from the prefetch thread.
   */
  int GetPrefetchedSteps();

  /**
   * 1 when the reader takes the file: particles only, never a mesh
   * (vtkFluidCastReader::CanReadFile). ParaView's reader factory asks this, so the reader
   * is offered for particle files only.
   */
  int CanReadFile(const char* fname);

protected:
  vtkPVFluidCastReader();
  ~vtkPVFluidCastReader() override;

  int RequestInformation(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;
  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;

  char* FileName = nullptr;
  /// The one reader behind every request (it keeps the series and the prefetched step).
  vtkNew<vtkFluidCastReader> Reader;

private:
  vtkPVFluidCastReader(const vtkPVFluidCastReader&) = delete;
  void operator=(const vtkPVFluidCastReader&) = delete;
};

#endif
