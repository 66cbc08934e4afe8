/**
 * @class   vtkFluidCastReader
 * @brief   Reads SPH particle files (.vtu, .vtp, legacy .vtk) with fluidcast's checked reader.
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

class FLUIDCASTRENDERING_EXPORT vtkFluidCastReader : public vtkPolyDataAlgorithm
{
public:
  static vtkFluidCastReader* New();
  vtkTypeMacro(vtkFluidCastReader, vtkPolyDataAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  ///@{
  /**
   * The file to read (.vtu, .vtp or .vtk).
   */
  vtkSetFilePathMacro(FileName);
  vtkGetFilePathMacro(FileName);
  ///@}

  /**
   * 1 when the file's extension is one this reader takes (.vtu, .vtp, .vtk), else 0.
   */
  static int CanReadFile(const char* fname);

protected:
  vtkFluidCastReader();
  ~vtkFluidCastReader() override;

  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;

  char* FileName = nullptr;

private:
  vtkFluidCastReader(const vtkFluidCastReader&) = delete;
  void operator=(const vtkFluidCastReader&) = delete;
};

#endif
