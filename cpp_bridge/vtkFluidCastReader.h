/**
 * @class   vtkFluidCastReader
 * @brief   Reads SPH particle files (.vtu, .vtp, legacy .vtk) and .pvd time series with
 *          fluidcast's checked reader, reading the next time step ahead.
 *
 * The output is a vtkPolyData: the file's points (double precision), one vertex cell per
 * point, its point-data arrays (with the numeric type they had in the file) and its field
 * data (e.g. TIME, support_radius). Cells of the file are not kept: every point is a particle.
 *
 * The reader is fluidcast's own (the one `fluidcast info` and `fluidcast render` use). It
 * checks every size a file states against what the file holds before allocating and is as
 * strict as VTK's readers, so a damaged or forged file (truncated, a compression header
 * claiming terabytes, a mislabelled header_type, ...) is reported with vtkErrorMacro naming
 * the file and the problem, the output stays empty and GetErrorCode() is
 * vtkErrorCode::FileFormatError; it never aborts the process. VTK 9.2's own XML readers abort
 * (std::bad_alloc) on some of those files.
 */
#ifndef vtkFluidCastReader_h
#define vtkFluidCastReader_h

#include "fluidcastRenderingModule.h" // for export macro
#include "vtkPolyDataAlgorithm.h"

#include <memory> // for std::unique_ptr

class FLUIDCASTRENDERING_EXPORT vtkFluidCastReader : public vtkPolyDataAlgorithm
{
public:
  static vtkFluidCastReader* New();
  vtkTypeMacro(vtkFluidCastReader, vtkPolyDataAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  ///@{
  /**
   * The file to read (.vtu, .vtp, .vtk, or a .pvd time series).
   */
  vtkSetFilePathMacro(FileName);
  vtkGetFilePathMacro(FileName);
  ///@}

  ///@{
  /**
   * For a .pvd series: read the next time step on a second thread once a step has been
   * read (default on). Off: each step is read when it is requested.
   */
  vtkSetMacro(Prefetch, vtkTypeBool);
  vtkGetMacro(Prefetch, vtkTypeBool);
  vtkBooleanMacro(Prefetch, vtkTypeBool);
  ///@}

  /**
   * How many of the time steps the reader has output came from the prefetch thread, since
   * it was made (what an animation gained from Prefetch).
   */
  vtkGetMacro(PrefetchedSteps, int);

  /**
   * Number of distinct times of the .pvd series (0 for a single file, or before the
   * pipeline's information pass).
   */
  int GetNumberOfTimeSteps() const;

  /**
   * 1 when the file's extension is one this reader takes (.vtu, .vtp, .vtk, .pvd), else 0.
   */
  static int CanReadFile(const char* fname);

protected:
  vtkFluidCastReader();
  ~vtkFluidCastReader() override;

  int RequestInformation(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;
  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;

  char* FileName = nullptr;
  vtkTypeBool Prefetch = 1;
  int PrefetchedSteps = 0;

private:
  struct vtkInternals;
  std::unique_ptr<vtkInternals> Internals;

  vtkFluidCastReader(const vtkFluidCastReader&) = delete;
  void operator=(const vtkFluidCastReader&) = delete;
};

#endif
