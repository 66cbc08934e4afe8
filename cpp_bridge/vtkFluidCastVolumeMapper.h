/**
 * @class   vtkFluidCastVolumeMapper
 * @brief   Direct volume rendering of SPH particles (a vtkPointSet) with fluidcast.
 *
 * The input is a vtkPointSet (vtkPolyData, vtkUnstructuredGrid) whose points are SPH
 * particles. Each render reconstructs the selected point array on the fly with the SPH kernel
 * (Shepard-normalised, as vtkSPHInterpolator with ShepardNormalization on) and ray casts it
 * with fluidcast's adaptive renderer (Hochstetter et al. 2016) into the renderer's viewport:
 * no resampling onto a grid.
 *
 * Like other volume mappers it reads the vtkVolume's vtkVolumeProperty: the colour transfer
 * function, the scalar opacity function and the scalar opacity unit distance (component 0),
 * and selects its array with SelectScalarArray / SetScalarMode (point data only) and
 * SetVectorMode / SetVectorComponent for vectors (vtkSmartVolumeMapper's constants; the
 * default, DISABLED, renders a vector's magnitude as ParaView does).
 *
 * The particles' support radius H (world units; the kernel vanishes beyond it) comes from
 * SupportRadius if > 0, else RadiusScale x RadiusArray, else the input's field data
 * "support_radius", else twice the mean particle spacing. Particle volumes come from
 * "mass"/"m" and "density"/"rho" point arrays when present, else "volume", else uniform.
 *
 * The image is composited over what the render window already holds and respects the depth
 * of opaque geometry drawn before it: rays stop at the depth buffer, so particles behind a
 * surface are hidden and particles in front of it cover it.
 *
 * Frames render on the CPU or on a GPU (wgpu compute, f32) as Backend says: AUTO (default)
 * takes a hardware GPU when there is one and the CPU otherwise, never a software driver; GPU
 * takes the best adapter of any kind (Mesa's lavapipe too). The GPU device, its pipelines and
 * buffers are opened on the first frame and live as long as the mapper.
 *
 * Errors (no points, missing array, NaN radius, ...) are reported with vtkErrorMacro naming
 * the problem; nothing is drawn then.
 */
#ifndef vtkFluidCastVolumeMapper_h
#define vtkFluidCastVolumeMapper_h

#include "fluidcastRenderingModule.h" // for export macro
#include "vtkAbstractVolumeMapper.h"
#include "vtkVolumeMapper.h" // for the blend mode constants

#include <functional> // for std::function
#include <memory>     // for std::unique_ptr
#include <string> // for std::string
#include <vector> // for std::vector

class vtkCamera;
class vtkPointSet;
class vtkRenderWindow;
class vtkRenderer;
class vtkVolume;

class FLUIDCASTRENDERING_EXPORT vtkFluidCastVolumeMapper : public vtkAbstractVolumeMapper
{
public:
  static vtkFluidCastVolumeMapper* New();
  vtkTypeMacro(vtkFluidCastVolumeMapper, vtkAbstractVolumeMapper);
  void PrintSelf(ostream& os, vtkIndent indent) override;

  /**
   * The particles: points with point data (vtkPolyData, vtkUnstructuredGrid, ...). Or
   * connect a pipeline with SetInputConnection.
   */
  void SetInputData(vtkPointSet* input);

  ///@{
  /**
   * One support radius H for all particles, in world units. 0 (default): use RadiusArray,
   * else the field data "support_radius", else twice the mean particle spacing. Negative,
   * infinite or NaN values are refused (see CheckSetting).
   */
  virtual void SetSupportRadius(double value);
  vtkGetMacro(SupportRadius, double);
  ///@}

  ///@{
  /**
   * Point array holding a per-particle radius (e.g. a smoothing length h); H = RadiusScale x
   * value. Used when SupportRadius is 0. Empty/null: none.
   */
  vtkSetStringMacro(RadiusArray);
  vtkGetStringMacro(RadiusArray);
  virtual void SetRadiusScale(double value);
  vtkGetMacro(RadiusScale, double);
  ///@}

  ///@{
  /**
   * SPH kernel: "cubic" (default), "quintic", "wendland-c2", "wendland-c4", "poly6",
   * "gaussian" (as `fluidcast render --kernel`).
   */
  virtual void SetKernel(const char* value);
  vtkGetStringMacro(Kernel);
  /**
   * The name of kernel `index` in fluidcast's list (0 cubic, 1 quintic, 2 wendland-c2,
   * 3 wendland-c4, 4 poly6, 5 gaussian: ParaView's FluidCastKernel), "" past its end.
   */
  static std::string GetKernelName(int index);

  /**
   * Why `value` is refused for the numeric property `property` ("SupportRadius",
   * "ErrorTolerance", ...; ParaView's "FluidCast" prefix may be given), or an empty string
   * when it is taken. The library's one table of settings decides, as for the CLI's options
   * and the Python package's arguments. Every numeric Set method below checks its value here:
   * a refused value is reported as a VTK error naming the property and the mapper keeps the
   * value it had, so one bad value (inf, NaN, a negative radius) never reaches a render.
   */
  static std::string CheckSetting(const char* property, double value);
  ///@}

  ///@{
  /**
   * The names Field and RBFClassification take, by index in fluidcast's lists (the Rust side's,
   * in the order of ParaView's FluidCastField: 0 csph, 1 sph, 2 density, 3 rbf; and
   * FluidCastRBFClassification: 0 post, 1 pre); "" past their ends.
   */
  static std::string GetFieldName(int index);
  static std::string GetRBFClassificationName(int index);
  /** RBFNoise's names by index (ParaView's FluidCastRBFNoise: 0 blue, 1 white). */
  static std::string GetRBFNoiseName(int index);
  ///@}

  ///@{
  /**
   * The field rendered, as `fluidcast render --field`: "csph" (default: the Shepard-normalised
   * SPH field of the array), "sph" (the plain SPH sum), "density", or "rbf": the
   * attribute-aware RBF field of Morrical et al. 2023. For "rbf" each particle is a truncated
   * Gaussian reaching RBFRadius (world units; <= 0, the default: its support radius), weighted
   * by the scalar opacity function at its value (the density map), coloured by
   * RBFClassification "post" (default: blend the values, then colour them) or "pre" (colour
   * each particle, then blend the colours); without an array the density itself is colour
   * mapped. It is ray marched with blue-noise jitter on the Backend's device (ErrorTolerance
   * does not apply), SamplesPerPixel passes per render; still renders of an unchanged view
   * accumulate passes up to ProgressivePasses (ParaView's OSPRay "Samples Per Pixel" and
   * "Progressive Passes"): render again to refine. With Shadows on, single scattering toward
   * a directional light from world direction LightDirection (0,0,0, the default: from above
   * and behind the camera), a fully shadowed point keeping ShadowAmbient of the light; for
   * the RBF field and the SPH fields alike (an SPH field is then marched the same stochastic
   * way, with the same passes, on the CPU: the GPU's march sums Gaussians).
   */
  virtual void SetField(const char* value);
  vtkGetStringMacro(Field);
  virtual void SetRBFClassification(const char* value);
  vtkGetStringMacro(RBFClassification);
  virtual void SetRBFRadius(double value);
  vtkGetMacro(RBFRadius, double);
  virtual void SetSamplesPerPixel(int value);
  vtkGetMacro(SamplesPerPixel, int);
  virtual void SetProgressivePasses(int value);
  vtkGetMacro(ProgressivePasses, int);
  vtkSetMacro(Shadows, vtkTypeBool);
  vtkGetMacro(Shadows, vtkTypeBool);
  vtkBooleanMacro(Shadows, vtkTypeBool);
  vtkSetVector3Macro(LightDirection, double);
  vtkGetVector3Macro(LightDirection, double);
  virtual void SetShadowAmbient(double value);
  vtkGetMacro(ShadowAmbient, double);
  /**
   * The RBF radius map: points (position on the colour map's range 0..1, radius factor >= 0),
   * linear between them; a factor of 0 hides particles. None (default): 1 everywhere. A change
   * refits the field's BVH instead of rebuilding it.
   */
  void AddRBFRadiusMapPoint(double position, double factor);
  void RemoveAllRBFRadiusMapPoints();
  int GetNumberOfRBFRadiusMapPoints() { return static_cast<int>(this->RBFRadiusMap.size() / 2); }
  ///@}

  ///@{
  /**
   * Screen-space error tolerance E_I: the adaptive renderer keeps each pixel within about
   * E_I (0..1, per channel) of full-rate sampling. Default 0.004 (about 1/255); 0 samples
   * every depth at full rate.
   */
  virtual void SetErrorTolerance(double value);
  vtkGetMacro(ErrorTolerance, double);
  ///@}

  /** Where frames render (see the class description). */
  enum BackendType
  {
    AUTO = 0,
    CPU = 1,
    GPU = 2
  };

  ///@{
  /**
   * Where frames render: AUTO (default: a hardware GPU, else the CPU), CPU or GPU.
   */
  vtkSetClampMacro(Backend, int, AUTO, GPU);
  vtkGetMacro(Backend, int);
  void SetBackendToAuto() { this->SetBackend(AUTO); }
  void SetBackendToCPU() { this->SetBackend(CPU); }
  void SetBackendToGPU() { this->SetBackend(GPU); }
  /** "auto", "cpu" or "gpu" (the names fluidcast's CLI takes for --backend). */
  std::string GetBackendAsString();
  ///@}

  ///@{
  /**
   * A GPU adapter by a part of its name ("nvidia", "llvmpipe", ...); empty/null (default): the
   * best one (the FLUIDCAST_ADAPTER environment variable applies then).
   */
  vtkSetStringMacro(Adapter);
  vtkGetStringMacro(Adapter);
  ///@}

  ///@{
  /**
   * Most memory (MiB) one render may take beyond the particles the mapper holds: above it,
   * the view is rendered in screen tiles, each with only the particles that reach it, to the
   * same image (but for the adaptive plan's probe, which each tile decides for itself: then
   * within the plan's error). 0 (default): no limit. A limit too small for the image and a minimal tile is
   * an error (nothing is drawn).
   */
  virtual void SetMemoryLimit(double value);
  vtkGetMacro(MemoryLimit, double);
  ///@}

  ///@{
  /**
   * The most kernel evaluations a frame may be estimated to take before it runs (each
   * particle's footprint in pixels times the depth samples through it): above it nothing is
   * drawn and the error says how much the view needs, rather than rendering for minutes (a
   * support radius far too large, a camera inside the fluid). 0 (default): 5e10.
   */
  virtual void SetWorkLimit(double value);
  vtkGetMacro(WorkLimit, double);
  ///@}

  ///@{
  /**
   * Particle level of detail (Fraedrich et al. 2010), in pixels: the particles are merged
   * into a hierarchy once per data set (blocks of 2x2x2 cells, volume, mass and the array's
   * volume-weighted mean kept; blocks at the edge of the particles are not merged), and each
   * render draws every part of the view at the coarsest level whose cells are at most this
   * many pixels at its depth. It pays where particles are about a pixel or smaller (millions
   * of particles); `fluidcast bench --lod` measures its speed and error. 0 (default): every
   * particle. Not with the RBF field or shadows, nor iso-surfaces of another array (errors).
   */
  virtual void SetLODTolerance(double value);
  vtkGetMacro(LODTolerance, double);
  ///@}

  ///@{
  /**
   * How the volume is sampled, as `fluidcast render --mode`: "auto" (default: adaptive, or the
   * exact reference caster with iso-surfaces unless Backend is GPU), "adaptive", "reference" or
   * "perspective-grid" (Fraedrich et al. 2010, GridCell pixels per column, 1..64). GetModeName
   * gives the names by index (ParaView's FluidCastMode).
   */
  virtual void SetMode(const char* value);
  vtkGetStringMacro(Mode);
  virtual void SetGridCell(int value);
  vtkGetMacro(GridCell, int);
  static std::string GetModeName(int index);
  ///@}

  ///@{
  /**
   * The adaptive plan's switches (all on by default), as the CLI's --no-probe,
   * --no-superpixels, --no-surface-cells and --no-interpolation turn them off: the probe of
   * an eighth of the bundles first, super-pixels, cells with surface particles forced to full
   * rate, image-space interpolation in the relaxed mode.
   */
  vtkSetMacro(Probe, vtkTypeBool);
  vtkGetMacro(Probe, vtkTypeBool);
  vtkBooleanMacro(Probe, vtkTypeBool);
  vtkSetMacro(SuperPixels, vtkTypeBool);
  vtkGetMacro(SuperPixels, vtkTypeBool);
  vtkBooleanMacro(SuperPixels, vtkTypeBool);
  vtkSetMacro(SurfaceCells, vtkTypeBool);
  vtkGetMacro(SurfaceCells, vtkTypeBool);
  vtkBooleanMacro(SurfaceCells, vtkTypeBool);
  vtkSetMacro(Interpolation, vtkTypeBool);
  vtkGetMacro(Interpolation, vtkTypeBool);
  vtkBooleanMacro(Interpolation, vtkTypeBool);
  ///@}

  ///@{
  /**
   * Render each view in at least this many screen tiles (the CLI's --tiles; the same image in
   * less memory). 0 (default): as MemoryLimit needs. GetLastTiles: the tiles of the last frame.
   */
  virtual void SetTiles(int value);
  vtkGetMacro(Tiles, int);
  vtkGetMacro(LastTiles, vtkIdType);
  ///@}

  ///@{
  /**
   * The rest of the plan, as the CLI's options of the same names (see each): the error
   * analysis (Relax, Strict), the grid (BundleSize, DepthSamples, SamplingScale), the
   * perspective grid's OcclusionCulling, and the RBF march (RBFNoise "blue" or "white",
   * RBFSeed, RBFLeafSize, RBFStep, ShadowSamples).
   * Relax: The relaxation E_relax in [0, 1] (1, the default: ignore the lateral variation inside cells when estimating errors; 0: the strict bound). fluidcast render --relax.
   * Strict: The strict error bound: no relaxation, super-pixels or interpolation, so no pixel differs from full rate by more than ErrorTolerance. fluidcast render --strict.
   * BundleSize: Ray bundle side D_xy in pixels (1..64; 8 by default; the GPU takes at most 8). fluidcast render --bundle.
   * DepthSamples: Depth samples per cell D_z, a power of two in 1..64 (16 by default). fluidcast render --depth-samples.
   * SamplingScale: Depth samples per ray relative to the default (> 0; 1 by default). fluidcast render --sampling-scale.
   * OcclusionCulling: Perspective grid: skip the tiles of columns that no still-marching pixel reads (on by default; off draws the same image, slower). fluidcast render --no-occlusion-culling turns it off.
   * RBFSeed: RBF: seed of the per-pixel jitter. fluidcast render --seed.
   * RBFLeafSize: RBF: particles per BVH leaf (1..64). fluidcast render --leaf-size.
   * RBFStep: RBF: the step along each ray (world units); <= 0 (default): half the median particle's standard deviation over SamplingScale. fluidcast render --rbf-step.
   * ShadowSamples: RBF shadows: shadow rays per pixel and pass (1..1024). fluidcast render --shadow-samples.
   */
  virtual void SetRelax(double value);
  vtkGetMacro(Relax, double);
  vtkSetMacro(Strict, vtkTypeBool);
  vtkGetMacro(Strict, vtkTypeBool);
  vtkBooleanMacro(Strict, vtkTypeBool);
  virtual void SetBundleSize(int value);
  vtkGetMacro(BundleSize, int);
  virtual void SetDepthSamples(int value);
  vtkGetMacro(DepthSamples, int);
  virtual void SetSamplingScale(double value);
  vtkGetMacro(SamplingScale, double);
  vtkSetMacro(OcclusionCulling, vtkTypeBool);
  vtkGetMacro(OcclusionCulling, vtkTypeBool);
  vtkBooleanMacro(OcclusionCulling, vtkTypeBool);
  virtual void SetRBFSeed(int value);
  vtkGetMacro(RBFSeed, int);
  virtual void SetRBFLeafSize(int value);
  vtkGetMacro(RBFLeafSize, int);
  virtual void SetRBFStep(double value);
  vtkGetMacro(RBFStep, double);
  virtual void SetShadowSamples(int value);
  vtkGetMacro(ShadowSamples, int);
  virtual void SetRBFNoise(const char* value);
  vtkGetStringMacro(RBFNoise);
  ///@}

  ///@{
  /**
   * Light the volume itself in composite mode (fluidcast render --shade-volume): Blinn–Phong
   * with the volume property's Ambient, Diffuse, Specular and SpecularPower and a headlight,
   * at the field's gradient; drawn by the exact reference caster. Off by default (the
   * property's Shade then applies to iso-surfaces only, as ParaView turns Shade on by
   * default).
   */
  vtkSetMacro(ShadeVolume, vtkTypeBool);
  vtkGetMacro(ShadeVolume, vtkTypeBool);
  vtkBooleanMacro(ShadeVolume, vtkTypeBool);
  ///@}

  ///@{
  /**
   * Iso-surfaces, as vtkGPUVolumeRayCastMapper draws them: with BlendMode
   * vtkVolumeMapper::ISOSURFACE_BLEND the surfaces at the vtkVolumeProperty's
   * GetIsoSurfaceValues() are drawn, found exactly along each ray and lit with the property's
   * Shade, Ambient, Diffuse, Specular and SpecularPower (a headlight; Shade off: flat colour),
   * coloured by the rendered array through the colour transfer function.
   * vtkVolumeMapper::COMPOSITE_BLEND (default): the volume. Other blend modes are errors.
   * IsoSurfaceField: "colour" (default: Σ V W with V = m/ρ, about 1 inside the fluid, so 0.5
   * is the free surface), "density" (Σ m W) or a point array's name (its CSPH field).
   * IsoSurfaceOpacity in (0, 1]; IsoSurfaceWithVolume also composites the volume, in depth
   * order with the surfaces. Surfaces follow the Backend as in the CLI: with GPU they stop the
   * adaptive volume on the GPU; otherwise the exact reference ray caster draws them (CPU), with
   * a note. In composite
   * mode the volume is not shaded (the property's Shade is read for surfaces only; shaded
   * volume rendering is the CLI's and library's --shade-volume for now).
   */
  vtkSetMacro(BlendMode, int);
  vtkGetMacro(BlendMode, int);
  void SetBlendModeToComposite() { this->SetBlendMode(vtkVolumeMapper::COMPOSITE_BLEND); }
  void SetBlendModeToIsoSurface() { this->SetBlendMode(vtkVolumeMapper::ISOSURFACE_BLEND); }
  vtkSetStringMacro(IsoSurfaceField);
  vtkGetStringMacro(IsoSurfaceField);
  virtual void SetIsoSurfaceOpacity(double value);
  vtkGetMacro(IsoSurfaceOpacity, double);
  vtkSetMacro(IsoSurfaceWithVolume, vtkTypeBool);
  vtkGetMacro(IsoSurfaceWithVolume, vtkTypeBool);
  vtkBooleanMacro(IsoSurfaceWithVolume, vtkTypeBool);
  ///@}

  ///@{
  /**
   * How a vector array becomes a scalar: vtkSmartVolumeMapper's DISABLED (-1, default:
   * magnitude for vectors, the value for scalars), MAGNITUDE (0) or COMPONENT (1, with
   * VectorComponent).
   */
  vtkSetClampMacro(VectorMode, int, -1, 1);
  vtkGetMacro(VectorMode, int);
  vtkSetMacro(VectorComponent, int);
  vtkGetMacro(VectorComponent, int);
  ///@}

  ///@{
  /**
   * Interactive rendering, as VTK's ray cast mappers do it (vtkFixedPointVolumeRayCastMapper's
   * names). With AutoAdjustSampleDistances on (the default) each frame fits the time the
   * renderer allocates to the volume (vtkProp::GetAllocatedRenderTime: 1 / the render window's
   * DesiredUpdateRate, which VTK's interactors and ParaView's interactive renders raise while
   * the camera moves): it casts one ray per ImageSampleDistance × ImageSampleDistance pixels,
   * the smallest distance in [MinimumImageSampleDistance, MaximumImageSampleDistance] whose
   * predicted time fits (a fixed part plus a part per ray, the line through the last two
   * frames of different sizes; per ray alone after the first frame), and the GPU stretches the
   * image over the viewport, interpolating bilinearly. Where no distance fits, the finest one
   * predicted within a fifth of the MaximumImageSampleDistance's time: past it coarser rays
   * would blur the image for next to no speed, the grid and the plan taking most of the
   * frame. Still renders (allocated
   * seconds to minutes) get full resolution. Off: every frame uses ImageSampleDistance.
   * Distances are whole pixels.
   */
  vtkSetMacro(AutoAdjustSampleDistances, vtkTypeBool);
  vtkGetMacro(AutoAdjustSampleDistances, vtkTypeBool);
  vtkBooleanMacro(AutoAdjustSampleDistances, vtkTypeBool);
  vtkSetClampMacro(ImageSampleDistance, int, 1, 64);
  vtkGetMacro(ImageSampleDistance, int);
  vtkSetClampMacro(MinimumImageSampleDistance, int, 1, 64);
  vtkGetMacro(MinimumImageSampleDistance, int);
  vtkSetClampMacro(MaximumImageSampleDistance, int, 1, 64);
  vtkGetMacro(MaximumImageSampleDistance, int);
  /** The distance the last frame used (1: every pixel cast). */
  vtkGetMacro(LastImageSampleDistance, int);
  ///@}

  ///@{
  /**
   * Cropping, with vtkVolumeMapper's names: with Cropping on, only the part of the field
   * inside the world-space box CroppingRegionPlanes (xmin, xmax, ymin, ymax, zmin, zmax) is
   * rendered (vtkVolumeMapper's VTK_CROP_SUBVOLUME; the other region flags are not offered).
   * Particles outside the box still contribute to the field inside it. Boxes that partition
   * space render to images that, composited in visibility order, equal the uncropped image:
   * ParaView's fluidcast representation gives each MPI rank the box it owns this way. With
   * Cropping on, an input with no points draws nothing without an error (an empty region).
   */
  vtkSetClampMacro(Cropping, vtkTypeBool, 0, 1);
  vtkGetMacro(Cropping, vtkTypeBool);
  vtkBooleanMacro(Cropping, vtkTypeBool);
  vtkSetVector6Macro(CroppingRegionPlanes, double);
  vtkGetVectorMacro(CroppingRegionPlanes, double, 6);
  ///@}

  ///@{
  /**
   * Sample depths shared by the parts of one data set (ParaView's representation uses it in
   * parallel; other code rarely needs it). Each frame places its depth samples over the view
   * depths its particles' supports span; renderers that each hold a part of one data set (MPI
   * ranks) must place them over the whole's span instead, or their images will not add up to
   * the image of the whole. ComputeSupportDepthRange gives this input's span (zmin, zmax, view
   * depth in world units) for `cam` (0 without particles, or on bad input: see GetLastError);
   * the parts reduce them (min zmin, max zmax) and each calls SetSharedSupportDepthRange
   * before rendering. Setting it does not modify the mapper (the particles stay prepared).
   */
  int ComputeSupportDepthRange(vtkCamera* cam, double range[2]);
  void SetSharedSupportDepthRange(double zmin, double zmax);
  void ClearSharedSupportDepthRange();
  ///@}

  ///@{
  /**
   * After a render: particles used, the largest support radius (world units), depth samples
   * composited and the frame's wall-clock time in this mapper (milliseconds).
   */
  vtkGetMacro(LastParticleCount, vtkIdType);
  vtkGetMacro(LastMaxRadius, double);
  vtkGetMacro(LastSamples, vtkIdType);
  vtkGetMacro(LastRenderMilliseconds, double);
  /** Where the last frame rendered: "CPU (N threads)" or "GPU: <adapter>". */
  const char* GetLastDevice() { return this->LastDevice.c_str(); }
  /**
   * Why the last render or UpdateParticles drew or prepared nothing (the message also
   * reported with vtkErrorMacro); "" when it succeeded.
   */
  const char* GetLastError() { return this->LastError.c_str(); }
  ///@}

  /**
   * Updates the input and hands the particles to fluidcast now, as the first render would:
   * the scalar array, the support radii, the particle volumes and the neighbour grid (what
   * does not depend on the view) are checked and built. Returns 1 on success, 0 on bad
   * input, with the reason in GetLastError() and reported with vtkErrorMacro. Scripts call it
   * to fail where they add the particles, not at the first render.
   */
  int UpdateParticles();

  /**
   * Bounds of the input's finite points grown by the particles' support radius (the extent
   * of the field), cut to CroppingRegionPlanes when Cropping is on. Always finite, or
   * uninitialized when no point is finite: a view's ResetCamera never sees inf or NaN.
   */
  double* GetBounds() override;
  void GetBounds(double bounds[6]) override { this->Superclass::GetBounds(bounds); }

  void Render(vtkRenderer* ren, vtkVolume* vol) override;
  /** Releases the texture that shows the rendered image in `win`. */
  void ReleaseGraphicsResources(vtkWindow* win) override;

protected:
  vtkFluidCastVolumeMapper();
  /** CheckSetting, with a refusal reported as an error that names what is kept. */
  bool AcceptSetting(const char* property, double value, double kept);
  /** Whether the named property `property` takes `value` (bridge check_name); an error if not. */
  bool AcceptName(const char* property, const char* value, const char* kept);
  /**
   * Runs `render` (the bridge's render) on a worker thread while this thread reports its
   * progress (UpdateProgress) and polls `win`'s CheckAbortStatus, cancelling the render when
   * VTK asks to abort. Returns false when it was cancelled; rethrows the render's error.
   */
  bool RenderWatched(vtkRenderWindow* win, const std::function<void()>& render);
  ~vtkFluidCastVolumeMapper() override;

  int FillInputPortInformation(int port, vtkInformation* info) override;

  double SupportRadius = 0.0;
  char* RadiusArray = nullptr;
  double RadiusScale = 1.0;
  char* Kernel = nullptr;
  double ErrorTolerance = 0.004;
  char* Field = nullptr;
  char* RBFClassification = nullptr;
  double RBFRadius = 0.0;
  int SamplesPerPixel = 1;
  int ProgressivePasses = 1;
  vtkTypeBool Shadows = 0;
  double LightDirection[3] = { 0, 0, 0 };
  double ShadowAmbient = 0.25;
  /** (position, factor) pairs, flattened. */
  std::vector<double> RBFRadiusMap;
  int Backend = AUTO;
  char* Adapter = nullptr;
  double MemoryLimit = 0.0;
  double WorkLimit = 0.0;
  double LODTolerance = 0.0;
  char* Mode = nullptr;
  int GridCell = 1;
  vtkTypeBool Probe = 1;
  vtkTypeBool SuperPixels = 1;
  vtkTypeBool SurfaceCells = 1;
  vtkTypeBool Interpolation = 1;
  int Tiles = 0;
  vtkIdType LastTiles = 0;
  double Relax = 1.0;
  vtkTypeBool Strict = 0;
  int BundleSize = 8;
  int DepthSamples = 16;
  double SamplingScale = 1.0;
  vtkTypeBool OcclusionCulling = 1;
  int RBFSeed = 0;
  int RBFLeafSize = 8;
  double RBFStep = 0.0;
  int ShadowSamples = 1;
  char* RBFNoise = nullptr;
  vtkTypeBool ShadeVolume = 0;
  int VectorMode = -1;
  int VectorComponent = 0;
  int BlendMode = vtkVolumeMapper::COMPOSITE_BLEND;
  char* IsoSurfaceField = nullptr;
  double IsoSurfaceOpacity = 1.0;
  vtkTypeBool IsoSurfaceWithVolume = 0;
  vtkTypeBool AutoAdjustSampleDistances = 1;
  int ImageSampleDistance = 1;
  int MinimumImageSampleDistance = 1;
  int MaximumImageSampleDistance = 8;
  int LastImageSampleDistance = 1;
  vtkTypeBool Cropping = 0;
  double CroppingRegionPlanes[6] = { 0, 1, 0, 1, 0, 1 };
  /** (zmin, zmax) when set with SetSharedSupportDepthRange, else zmin > zmax. */
  double SharedSupportDepths[2] = { 1, 0 };

  vtkIdType LastParticleCount = 0;
  double LastMaxRadius = 0.0;
  vtkIdType LastSamples = 0;
  double LastRenderMilliseconds = 0.0;
  std::string LastDevice;
  std::string LastError;

private:
  vtkFluidCastVolumeMapper(const vtkFluidCastVolumeMapper&) = delete;
  void operator=(const vtkFluidCastVolumeMapper&) = delete;

  /** Updates the input algorithm; true when there is an input and it has no points. */
  bool InputIsEmpty();
  /** Updates the input algorithm; the input if it is a vtkPointSet with points. */
  vtkPointSet* UpdatedInput();
  /** Hands the input to the Rust renderer when it or the settings changed (else the last
   * outcome, its error message included). */
  bool Upload(vtkPointSet* input);
  bool UploadNow(vtkPointSet* input);
  /** The image sample distance for this frame (see AutoAdjustSampleDistances). */
  int ChooseImageSampleDistance(vtkVolume* vol, int w, int h);
  /** View depth of the opaque geometry drawn so far for each of the sw × sh rays cast over
   * the w × h viewport (rows top first; infinity where none), empty when there is none. */
  std::vector<float> DepthLimits(vtkRenderer* ren, int w, int h, int x0, int y0, int sw, int sh);

  struct Internals;
  std::unique_ptr<Internals> Impl;
};

#endif
