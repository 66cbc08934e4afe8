/**
 * @class   vtkFluidCastRepresentation
 * @brief   ParaView representation "fluidcast": SPH particles volume-rendered on the fly.
 *
 * A volume representation for point sets (vtkPolyData, vtkUnstructuredGrid) that draws the
 * points as SPH particles with vtkFluidCastVolumeMapper: the colour array, colour map and
 * scalar opacity function come from ParaView's colour-map editor like the "Volume"
 * representation's; the support radius, radius array, kernel and error tolerance are its
 * own properties (fluidcast_representation.xml). With no radius set, the data's
 * "support_radius" field data is used, else twice the mean particle spacing.
 */
#ifndef vtkFluidCastRepresentation_h
#define vtkFluidCastRepresentation_h

#include "fluidcastParaViewRepresentationModule.h" // for export macro
#include "vtkVolumeRepresentation.h"

#include "vtkNew.h"          // for vtkNew
#include "vtkSmartPointer.h" // for vtkSmartPointer

class vtkFluidCastVolumeMapper;
class vtkPointSet;

class FLUIDCASTPARAVIEWREPRESENTATION_EXPORT vtkFluidCastRepresentation
  : public vtkVolumeRepresentation
{
public:
  static vtkFluidCastRepresentation* New();
  vtkTypeMacro(vtkFluidCastRepresentation, vtkVolumeRepresentation);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  int ProcessViewRequest(vtkInformationRequestKey* request_type, vtkInformation* inInfo,
    vtkInformation* outInfo) override;

  ///@{
  /**
   * Forwarded to vtkFluidCastVolumeMapper. SupportRadius <= 0 means "from RadiusArray, else
   * the field data support_radius, else from the particle spacing". RadiusArray "" or "None"
   * means no radius array. Kernel: 0 cubic, 1 quintic, 2 Wendland C2, 3 Wendland C4, 4 poly6,
   * 5 Gaussian. Backend: vtkFluidCastVolumeMapper::AUTO, CPU or GPU; Adapter: a GPU by a part
   * of its name ("" = the best).
   */
  void SetSupportRadius(double h);
  void SetRadiusArray(const char* name);
  void SetRadiusScale(double s);
  void SetKernel(int kernel);
  void SetErrorTolerance(double e);
  void SetBackend(int backend);
  void SetAdapter(const char* name);
  ///@}

  ///@{
  /**
   * Forwarded to vtkFluidCastVolumeMapper: interactive renders (ParaView's, while the camera
   * moves) cast one ray per ImageSampleDistance² pixels to fit the interactive frame time,
   * up to MaximumImageSampleDistance; still renders are full resolution. Auto off: every
   * render uses ImageSampleDistance.
   */
  void SetAutoAdjustSampleDistances(int on);
  void SetImageSampleDistance(int s);
  void SetMaximumImageSampleDistance(int s);
  ///@}

  /** The mapper, for scripts that read LastDevice, LastSamples, ... */
  vtkFluidCastVolumeMapper* GetFluidCastMapper() { return this->Mapper; }

protected:
  vtkFluidCastRepresentation();
  ~vtkFluidCastRepresentation() override;

  int FillInputPortInformation(int port, vtkInformation* info) override;
  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;
  bool AddToView(vtkView* view) override;
  bool RemoveFromView(vtkView* view) override;
  void UpdateMapperParameters();

  vtkNew<vtkFluidCastVolumeMapper> Mapper;
  vtkSmartPointer<vtkPointSet> Cache;

private:
  vtkFluidCastRepresentation(const vtkFluidCastRepresentation&) = delete;
  void operator=(const vtkFluidCastRepresentation&) = delete;
};

#endif
