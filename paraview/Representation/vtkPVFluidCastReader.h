/**
 * @class   vtkPVFluidCastReader
 * @brief   ParaView's face of vtkFluidCastReader: the "fluidcast particle reader".
 *
 * A thin source that runs vtkFluidCastReader (fluidcast's checked reader for .vtu, .vtp and
 * legacy .vtk particle files) and passes its vtkPolyData on. It exists so that the reader is
 * wrapped for ParaView's server manager with the plugin; see vtkFluidCastReader for what it
 * reads and how it reports damaged files (a VTK error, never an abort).
 */
#ifndef vtkPVFluidCastReader_h
#define vtkPVFluidCastReader_h

#include "fluidcastParaViewRepresentationModule.h" // for export macro
#include "vtkPolyDataAlgorithm.h"

class FLUIDCASTPARAVIEWREPRESENTATION_EXPORT vtkPVFluidCastReader : public vtkPolyDataAlgorithm
{
public:
  static vtkPVFluidCastReader* New();
  vtkTypeMacro(vtkPVFluidCastReader, vtkPolyDataAlgorithm);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  ///@{
  /**
   * The file to read (.vtu, .vtp or .vtk).
   */
  vtkSetFilePathMacro(FileName);
  vtkGetFilePathMacro(FileName);
  ///@}

  /**
   * 1 when the file's extension is one the reader takes, else 0 (ParaView's reader factory
   * asks this).
   */
  int CanReadFile(const char* fname);

protected:
  vtkPVFluidCastReader();
  ~vtkPVFluidCastReader() override;

  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;

  char* FileName = nullptr;

private:
  vtkPVFluidCastReader(const vtkPVFluidCastReader&) = delete;
  void operator=(const vtkPVFluidCastReader&) = delete;
};

#endif
