/**
 * @class   vtkFluidCastReader
 * @brief   Reads SPH particle files (.vtu, .vtp, legacy .vtk) and .pvd time series with
 *          fluidcast's checked reader, reading the next time step ahead.
 *
 * The output is a vtkPolyData: the file's points (double precision), one vertex cell per
 * point, its point-data arrays (with the numeric type they had in the file) and its field
 * data (e.g. TIME, support_radius). Every point is a particle.
 *
 * It reads particle files only. A file that holds more, which this reader would drop, is
 * refused with an error naming the file and what it holds: cells other than vertices and
 * poly-vertices (a mesh's tetrahedra, polygons, lines), cell data, or a data set type
 * other than an unstructured grid or poly data (a structured grid). VTK's and ParaView's own
 * readers keep all of it. CanReadFile() declines such files, so that ParaView's reader
 * factory never offers this reader for them.
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
   * 1 when this reader takes the file: a .vtu, .vtp or legacy .vtk of particles (points,
   * at most vertex or poly-vertex cells, no cell data), a .pvd whose first time step lists
   * only such files, or such a file that is damaged (reading it then reports what is
   * wrong). 0 for a mesh, a structured grid, any other file, or one that does not exist.
   * It reads the file's XML head and cell types (an appended .vtu/.vtp) or the whole file
   * (legacy, inline XML).
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
