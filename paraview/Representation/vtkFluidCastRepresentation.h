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
 *
 * In parallel (pvbatch/pvserver on several MPI ranks) each rank owns a box of space: the
 * particles are redistributed with a halo of neighbours (fluidcastDistribute.h), each rank
 * renders the field inside its box only, and ParaView composites the ranks' images in
 * visibility order of the boxes (USE_BOUNDS_FOR_REDISTRIBUTION ordered compositing), so
 * the image equals the single-process one. Where the pieces are gathered onto one process
 * instead (a client rendering locally), the halo copies are dropped.
 */
#ifndef vtkFluidCastRepresentation_h
#define vtkFluidCastRepresentation_h

#include "fluidcastParaViewRepresentationModule.h" // for export macro
#include "vtkVolumeRepresentation.h"

#include "vtkNew.h"          // for vtkNew
#include "vtkSmartPointer.h" // for vtkSmartPointer
#include "vtkTimeStamp.h"    // for vtkTimeStamp
#include "vtkWeakPointer.h"  // for vtkWeakPointer

class vtkFluidCastVolumeMapper;
class vtkPVRenderView;
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
  /** The mapper's MemoryLimit (MiB; 0: none): render in screen tiles to stay within it. */
  void SetMemoryLimit(double mib);
  /** The mapper's WorkLimit (kernel evaluations a frame may be estimated to take; 0: 5e10). */
  void SetWorkLimit(double evaluations);
  /** The mapper's LODTolerance (pixels; 0: every particle): particle level of detail. */
  void SetLODTolerance(double px);
  void SetBackend(int backend);
  void SetAdapter(const char* name);
  /**
   * The mapper's sampling: Mode (0 auto, 1 adaptive, 2 reference, 3 perspective grid: the
   * Rust side's list), GridCell, the plan's switches and Tiles.
   */
  void SetMode(int mode);
  void SetGridCell(int px);
  void SetProbe(int on);
  void SetSuperPixels(int on);
  void SetSurfaceCells(int on);
  void SetInterpolation(int on);
  void SetTiles(int tiles);
  /** The mapper's remaining plan settings (see vtkFluidCastVolumeMapper); RBFNoise 0 blue, 1 white. */
  void SetRelax(double v);
  void SetStrict(int v);
  void SetBundleSize(int v);
  void SetDepthSamples(int v);
  void SetSamplingScale(double v);
  void SetOcclusionCulling(int v);
  void SetRBFSeed(int v);
  void SetRBFLeafSize(int v);
  void SetRBFStep(double v);
  void SetShadowSamples(int v);
  void SetRBFNoise(int noise);
  void SetShadeVolume(int on);
  ///@}

  ///@{
  /**
   * The field (Field: 0 CSPH, 1 SPH, 2 density, 3 RBF) and the RBF field's options, forwarded
   * to vtkFluidCastVolumeMapper (RBFClassification: 0 post, 1 pre; LightDirection all 0:
   * from above and behind the camera). With the RBF field, still renders of an unchanged
   * view add SamplesPerPixel passes each, up to ProgressivePasses.
   */
  void SetField(int field);
  void SetRBFClassification(int classification);
  void SetRBFRadius(double r);
  void SetSamplesPerPixel(int n);
  void SetProgressivePasses(int n);
  void SetShadows(int on);
  void SetLightDirection(double x, double y, double z);
  void SetShadowAmbient(double a);
  /** The RBF radius map's points (position 0..1, factor); cleared first by ParaView. */
  void AddRBFRadiusMapPoint(double position, double factor);
  void RemoveAllRBFRadiusMapPoints();
  ///@}

  ///@{
  /**
   * Forwarded to vtkFluidCastVolumeMapper: interactive renders (ParaView's, while the camera
   * moves) cast one ray per ImageSampleDistance² pixels to fit the interactive frame time,
   * up to MaximumImageSampleDistance; still renders are full resolution. Auto off: every
   * render uses ImageSampleDistance. In parallel every rank must cast the same rays, so
   * frames use ImageSampleDistance there.
   */
  void SetAutoAdjustSampleDistances(int on);
  void SetImageSampleDistance(int s);
  void SetMaximumImageSampleDistance(int s);
  ///@}

  ///@{
  /**
   * Iso-surfaces (vtkFluidCastVolumeMapper's iso-surface blend mode): the values go to the
   * volume property's GetIsoSurfaceValues() (any: iso-surface blend mode; none: the volume);
   * the field, opacity and "with volume" to the mapper; shading (Shade, Ambient, Diffuse,
   * Specular, SpecularPower) to the volume property, whose lighting the mapper applies.
   */
  void SetNumberOfIsosurfaces(int n);
  void SetIsosurfaceValue(int i, double value);
  void SetIsosurfaceField(const char* name);
  void SetIsosurfaceOpacity(double opacity);
  void SetIsosurfaceWithVolume(int on);
  void SetShade(int on);
  void SetAmbient(double v);
  void SetDiffuse(double v);
  void SetSpecular(double v);
  void SetSpecularPower(double v);
  ///@}

  /** The mapper, for scripts that read LastDevice, LastSamples, ... */
  vtkFluidCastVolumeMapper* GetFluidCastMapper() { return this->Mapper; }

  ///@{
  /**
   * In parallel, after an update: the particles this rank owns and the halo copies it holds
   * of its neighbours' (0 and 0 in a single process), and its box (xmin, xmax, ...).
   */
  vtkGetMacro(OwnedParticles, vtkIdType);
  vtkGetMacro(HaloParticles, vtkIdType);
  vtkGetVector6Macro(Region, double);
  /** The mapper's last error ("" when its last render succeeded). */
  const char* GetLastError();
  /** The mapper's last frame: where it rendered ("CPU (N threads)", "GPU: adapter"). */
  const char* GetLastDevice();
  /** The mapper's last frame: the screen tiles it rendered in (0: one render). */
  vtkIdType GetLastTiles();
  ///@}

protected:
  vtkFluidCastRepresentation();
  ~vtkFluidCastRepresentation() override;

  int FillInputPortInformation(int port, vtkInformation* info) override;
  int RequestData(vtkInformation*, vtkInformationVector**, vtkInformationVector*) override;
  bool AddToView(vtkView* view) override;
  bool RemoveFromView(vtkView* view) override;
  void UpdateMapperParameters();
  /** In parallel: the whole data set's support depth range, reduced over the ranks, set on
   * the mapper so that every rank places its depth samples alike (collective). */
  void ShareSupportDepths(vtkPVRenderView* view);

  vtkNew<vtkFluidCastVolumeMapper> Mapper;
  vtkSmartPointer<vtkPointSet> Cache;
  /** What the mapper renders when the delivered piece is not this rank's own. */
  vtkSmartPointer<vtkPointSet> Gathered;
  vtkWeakPointer<vtkPointSet> GatheredFrom;
  vtkTimeStamp GatheredTime;
  /** True when this process redistributed the particles among several ranks. */
  bool Distributed = false;
  double Region[6] = { 0, -1, 0, -1, 0, -1 };
  /** Region as the mapper crops rays: its outer faces far out (fluidcastDistribute.h). */
  double CroppingPlanes[6] = { 0, -1, 0, -1, 0, -1 };
  vtkIdType OwnedParticles = 0;
  vtkIdType HaloParticles = 0;
  /** The AutoAdjustSampleDistances property (not applied in parallel). */
  int AutoAdjust = 1;

private:
  vtkFluidCastRepresentation(const vtkFluidCastRepresentation&) = delete;
  void operator=(const vtkFluidCastRepresentation&) = delete;
};

#endif
