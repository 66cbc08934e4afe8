// Tests of vtkFluidCastVolumeMapper in a real (offscreen, Xvfb) VTK render window.
//
//   TestFluidCastMapper window DATA.vtu ARRAY OUTDIR FLUIDCAST_CLI TOLERANCE
//       renders DATA with the mapper and with `fluidcast render` for the same camera,
//       transfer function and error tolerance (a number or "off"); the two 8-bit images must
//       agree within 2/255 per channel at full rate, 2 E_I + 1/255 when adaptive.
//   TestFluidCastMapper properties DATA.vtu ARRAY OUTDIR FLUIDCAST_CLI
//       sets SupportRadius, Kernel, VectorMode/VectorComponent and ErrorTolerance away from
//       their defaults: each must change the image (or the samples) as the CLI's matching
//       option does.
//   TestFluidCastMapper depth DATA.vtu ARRAY OUTDIR
//       an opaque box in front of, behind and cutting through the particles: the mapper must
//       respect the depth buffer (fails if it ignored it).
//   TestFluidCastMapper depthcut OUTDIR
//       a uniform slab cut by an opaque box under a perspective camera: the opacity in front
//       of the box follows the closed form 1 - exp(-sigma L) (depth-buffer unprojection).
//   TestFluidCastMapper bad DATA.vtu
//       bad input (missing array, no points, NaN radius, NaN coordinates) gives VTK errors,
//       no crash, nothing drawn.
//
// Exit code 0 = pass, 1 = fail, 77 = skipped (data not present).
#include "vtkActor.h"
#include "vtkCallbackCommand.h"
#include "vtkCamera.h"
#include "vtkColorTransferFunction.h"
#include "vtkCubeSource.h"
#include "vtkDoubleArray.h"
#include "vtkFieldData.h"
#include "vtkFloatArray.h"
#include "vtkFluidCastVolumeMapper.h"
#include "vtkImageData.h"
#include "vtkMath.h"
#include "vtkNew.h"
#include "vtkPNGReader.h"
#include "vtkPNGWriter.h"
#include "vtkPiecewiseFunction.h"
#include "vtkPointData.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkPolyDataMapper.h"
#include "vtkProperty.h"
#include "vtkRenderWindow.h"
#include "vtkRenderer.h"
#include "vtkUnsignedCharArray.h"
#include "vtkUnstructuredGrid.h"
#include "vtkVolume.h"
#include "vtkVolumeProperty.h"
#include "vtkWindowToImageFilter.h"
#include "vtkXMLUnstructuredGridReader.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace
{
const int W = 320, H = 240;

struct Image
{
  int w = 0, h = 0;
  std::vector<unsigned char> rgb; // bottom row first, as VTK
  int at(int i, int j, int c) const { return rgb[3 * (static_cast<size_t>(j) * w + i) + c]; }
};

Image FromImageData(vtkImageData* im)
{
  Image out;
  int* d = im->GetDimensions();
  out.w = d[0];
  out.h = d[1];
  vtkDataArray* s = im->GetPointData()->GetScalars();
  const int nc = s->GetNumberOfComponents();
  out.rgb.resize(3 * static_cast<size_t>(out.w) * out.h);
  for (vtkIdType p = 0; p < static_cast<vtkIdType>(out.w) * out.h; ++p)
  {
    for (int c = 0; c < 3; ++c)
    {
      out.rgb[3 * p + c] = static_cast<unsigned char>(s->GetComponent(p, std::min(c, nc - 1)));
    }
  }
  return out;
}

Image Grab(vtkRenderWindow* win)
{
  vtkNew<vtkWindowToImageFilter> w2i;
  w2i->SetInput(win);
  w2i->SetInputBufferTypeToRGB();
  w2i->ReadFrontBufferOff();
  // Read what the last Render() drew. Re-rendering here would go through the filter's
  // magnification code, which round-trips the view angle (30 -> 30.0000008) and so renders a
  // slightly different view than the camera says.
  w2i->ShouldRerenderOff();
  w2i->Update();
  return FromImageData(w2i->GetOutput());
}

void WritePng(const Image& img, const std::string& path)
{
  vtkNew<vtkImageData> im;
  im->SetDimensions(img.w, img.h, 1);
  vtkNew<vtkUnsignedCharArray> a;
  a->SetNumberOfComponents(3);
  a->SetNumberOfTuples(static_cast<vtkIdType>(img.w) * img.h);
  std::copy(img.rgb.begin(), img.rgb.end(), a->GetPointer(0));
  im->GetPointData()->SetScalars(a);
  vtkNew<vtkPNGWriter> wr;
  wr->SetFileName(path.c_str());
  wr->SetInputData(im);
  wr->Write();
}

/** A missing shared data set: a skip (77), or a failure with FLUIDCAST_REQUIRE_DATA=1. */
int MissingData(const std::string& data)
{
  const char* require = std::getenv("FLUIDCAST_REQUIRE_DATA");
  if (require && std::string(require) == "1")
  {
    std::cerr << "FAIL: FLUIDCAST_REQUIRE_DATA=1 but " << data << " is missing\n";
    return 1;
  }
  std::cout << "SKIP: " << data << " not present\n";
  return 77;
}

bool Exists(const std::string& p)
{
  std::ifstream f(p);
  return f.good();
}

vtkSmartPointer<vtkUnstructuredGrid> Read(const std::string& path)
{
  vtkNew<vtkXMLUnstructuredGridReader> r;
  r->SetFileName(path.c_str());
  r->Update();
  vtkSmartPointer<vtkUnstructuredGrid> ug = r->GetOutput();
  if (!ug || ug->GetNumberOfPoints() == 0)
  {
    std::cerr << "FAIL: VTK could not read " << path
              << " (on Debian 12, run with LD_PRELOAD=libfluidcast_expat_fix.so)\n";
    std::exit(1);
  }
  return ug;
}

/** The scene's transfer function: a few RGB nodes and an opacity ramp over [lo, hi]. */
struct TF
{
  double lo, hi;
  std::vector<double> rgb;     // x, r, g, b, ...
  std::vector<double> opacity; // x, a, ...
};

TF MakeTF(double lo, double hi)
{
  TF tf{ lo, hi, {}, {} };
  const double c[5][3] = { { 0.267, 0.005, 0.329 }, { 0.229, 0.322, 0.546 },
    { 0.128, 0.567, 0.551 }, { 0.369, 0.789, 0.383 }, { 0.993, 0.906, 0.144 } };
  for (int k = 0; k < 5; ++k)
  {
    tf.rgb.insert(tf.rgb.end(), { lo + (hi - lo) * k / 4.0, c[k][0], c[k][1], c[k][2] });
  }
  tf.opacity = { lo, 0.05, lo + 0.5 * (hi - lo), 0.3, hi, 0.8 };
  return tf;
}

vtkSmartPointer<vtkVolumeProperty> Property(const TF& tf, double unit)
{
  vtkNew<vtkColorTransferFunction> ctf;
  ctf->SetColorSpaceToRGB();
  for (size_t i = 0; i < tf.rgb.size(); i += 4)
  {
    ctf->AddRGBPoint(tf.rgb[i], tf.rgb[i + 1], tf.rgb[i + 2], tf.rgb[i + 3]);
  }
  vtkNew<vtkPiecewiseFunction> otf;
  for (size_t i = 0; i < tf.opacity.size(); i += 2)
  {
    otf->AddPoint(tf.opacity[i], tf.opacity[i + 1]);
  }
  auto prop = vtkSmartPointer<vtkVolumeProperty>::New();
  prop->SetColor(ctf);
  prop->SetScalarOpacity(otf);
  prop->SetScalarOpacityUnitDistance(unit);
  return prop;
}

void WritePreset(const TF& tf, const std::string& path)
{
  std::ofstream f(path);
  f.precision(17);
  f << "[{\"Name\": \"test\", \"ColorSpace\": \"RGB\", \"RGBPoints\": [";
  for (size_t i = 0; i < tf.rgb.size(); ++i)
  {
    f << (i ? ", " : "") << tf.rgb[i];
  }
  f << "], \"Points\": [";
  for (size_t i = 0; i < tf.opacity.size(); i += 2)
  {
    f << (i ? ", " : "") << tf.opacity[i] << ", " << tf.opacity[i + 1] << ", 0.5, 0";
  }
  f << "]}]\n";
}

void WriteCamera(vtkCamera* cam, const std::string& path)
{
  std::ofstream f(path);
  f.precision(17);
  const double* p = cam->GetPosition();
  const double* fp = cam->GetFocalPoint();
  const double* u = cam->GetViewUp();
  f << "{\"position\": [" << p[0] << ", " << p[1] << ", " << p[2] << "], \"focal_point\": ["
    << fp[0] << ", " << fp[1] << ", " << fp[2] << "], \"view_up\": [" << u[0] << ", " << u[1]
    << ", " << u[2] << "], \"view_angle\": " << cam->GetViewAngle()
    << ", \"parallel_projection\": " << (cam->GetParallelProjection() ? "true" : "false")
    << ", \"parallel_scale\": " << cam->GetParallelScale() << "}\n";
}

struct Scene
{
  vtkNew<vtkRenderer> ren;
  vtkNew<vtkRenderWindow> win;
  vtkNew<vtkFluidCastVolumeMapper> mapper;
  vtkNew<vtkVolume> volume;
  Scene()
  {
    win->SetOffScreenRendering(1);
    win->SetMultiSamples(0);
    win->SetSize(W, H);
    win->AddRenderer(ren);
    volume->SetMapper(mapper);
    ren->AddVolume(volume);
  }
  /** The particles' point array `array` through `prop`. */
  void Show(vtkPointSet* input, const std::string& array, vtkVolumeProperty* prop)
  {
    mapper->SetInputData(input);
    mapper->SelectScalarArray(array.c_str());
    mapper->SetScalarModeToUsePointFieldData();
    volume->SetProperty(prop);
  }
};

/** An unlit opaque box (the cube's bounds, set by the caller) in the scene's renderer. */
vtkActor* AddBox(Scene& s, vtkCubeSource* cube)
{
  vtkNew<vtkPolyDataMapper> cm;
  cm->SetInputConnection(cube->GetOutputPort());
  vtkNew<vtkActor> box;
  box->SetMapper(cm);
  box->GetProperty()->LightingOff();
  s.ren->AddActor(box); // the renderer keeps the actor (and its mapper) alive
  return box;
}

void SetupCamera(Scene& s, const double bounds[6])
{
  s.ren->ResetCamera(bounds);
  s.ren->GetActiveCamera()->Azimuth(30);
  s.ren->GetActiveCamera()->Elevation(20);
  s.ren->GetActiveCamera()->OrthogonalizeViewUp();
  s.ren->ResetCameraClippingRange(bounds);
}

struct Diff
{
  int max = 0;
  double mean = 0;
  size_t above2 = 0;
};

/** Pixels that are not the white background. */
size_t Drawn(const Image& img)
{
  size_t drawn = 0;
  for (size_t k = 0; k < img.rgb.size(); k += 3)
  {
    drawn += img.rgb[k] != 255 || img.rgb[k + 1] != 255 || img.rgb[k + 2] != 255;
  }
  return drawn;
}

Diff Compare(const Image& a, const Image& b)
{
  Diff d;
  for (size_t k = 0; k < a.rgb.size(); ++k)
  {
    const int e = std::abs(int(a.rgb[k]) - int(b.rgb[k]));
    d.max = std::max(d.max, e);
    d.mean += e;
    d.above2 += e > 2;
  }
  d.mean /= static_cast<double>(a.rgb.size());
  return d;
}

/**
 * The mapper properties a render sets, each mirrored by a `fluidcast render` option: the
 * defaults are the mapper's own.
 */
struct Settings
{
  std::string tolerance = "0.004"; // a number, or "off" (the mapper's 0)
  double supportRadius = 0;        // > 0: SupportRadius and --support-radius
  std::string kernel;              // non-empty: Kernel and --kernel
  int component = -1;              // >= 0: VectorMode COMPONENT and ARRAY:component
  std::string field;               // non-empty: Field and --field
  std::string classification;      // non-empty: RBFClassification and --classification
  int passes = 1;                  // RBF: still renders accumulated (ProgressivePasses), --spp
  bool shadows = false;            // RBF: Shadows and --shadows
  std::vector<double> radiusMap;   // RBF: AddRBFRadiusMapPoint and --radius-map
  double lod = 0;                  // > 0: LODTolerance and --lod
  double Tolerance() const { return tolerance == "off" ? 0.0 : std::stod(tolerance); }
  /** Largest channel difference (of 255) allowed between the mapper and the CLI. */
  int Allowed() const
  {
    // Full rate: both sample the same depths; the mapper's transfer function is VTK's
    // 1024-entry table of the same nodes, so only 8-bit rounding is left (2/255 allowed).
    // Adaptive: each image is within E_I of full rate and the two plans may choose
    // differently (their transfer-function bounds come from different control points), so
    // 2 E_I plus one level of rounding.
    const double e = Tolerance();
    return e > 0 ? static_cast<int>(std::ceil(2 * e * 255)) + 1 : 2;
  }
};

/** One view rendered by the mapper in a VTK window and by the CLI, with its sample counts. */
struct Pair
{
  Image mapper, cli;
  long long mapperSamples = 0, cliSamples = 0;
  double maxRadius = 0; // the mapper's largest support radius (world units)
};

/** The "samples" count from `fluidcast render --stats` JSON (-1 if absent). */
long long StatsSamples(const std::string& path)
{
  std::ifstream f(path);
  std::stringstream text;
  text << f.rdbuf();
  const std::string s = text.str();
  const size_t k = s.find("\"samples\":");
  return k == std::string::npos ? -1 : std::atoll(s.c_str() + k + 10);
}

/**
 * Renders DATA's ARRAY with the mapper (camera azimuth 30, elevation 20) and the same view,
 * transfer function and settings with `fluidcast render` into OUT (mapper.png, cli.png);
 * false with a FAIL line when either did not render.
 */
bool RenderPair(vtkUnstructuredGrid* ug, const std::string& data, const std::string& array,
  const std::string& out, const std::string& cli, const Settings& st, Pair& p)
{
  vtkDataArray* a = ug->GetPointData()->GetArray(array.c_str());
  if (!a)
  {
    std::cerr << "FAIL: no array " << array << "\n";
    return false;
  }
  double range[2];
  a->GetRange(range, st.component); // -1: magnitude
  TF tf = MakeTF(range[0], range[1]);
  const double unit = 0.1;

  Scene s;
  s.ren->SetBackground(1, 1, 1);
  s.Show(ug, array, Property(tf, unit));
  s.mapper->SetErrorTolerance(st.Tolerance());
  s.mapper->SetSupportRadius(st.supportRadius);
  s.mapper->SetLODTolerance(st.lod);
  if (!st.kernel.empty())
  {
    s.mapper->SetKernel(st.kernel.c_str());
  }
  if (st.component >= 0)
  {
    s.mapper->SetVectorMode(1);
    s.mapper->SetVectorComponent(st.component);
  }
  if (!st.field.empty() || st.shadows)
  {
    if (!st.field.empty())
    {
      s.mapper->SetField(st.field.c_str());
    }
    s.mapper->SetProgressivePasses(st.passes);
    s.mapper->SetShadows(st.shadows);
    if (!st.classification.empty())
    {
      s.mapper->SetRBFClassification(st.classification.c_str());
    }
    for (size_t k = 0; k + 1 < st.radiusMap.size(); k += 2)
    {
      s.mapper->AddRBFRadiusMapPoint(st.radiusMap[k], st.radiusMap[k + 1]);
    }
  }
  double b[6];
  s.mapper->GetBounds(b);
  SetupCamera(s, b);
  // Still renders of one view: each adds a pass up to ProgressivePasses (RBF).
  for (int k = 0; k < st.passes; ++k)
  {
    s.win->Render();
  }
  p.mapper = Grab(s.win);
  p.mapperSamples = s.mapper->GetLastSamples();
  p.maxRadius = s.mapper->GetLastMaxRadius();
  std::filesystem::create_directories(out);
  WritePng(p.mapper, out + "/mapper.png");
  std::cout << "mapper: " << s.mapper->GetLastParticleCount() << " particles, H = "
            << s.mapper->GetLastMaxRadius() << ", " << p.mapperSamples << " samples, "
            << s.mapper->GetLastRenderMilliseconds() << " ms\n";

  WriteCamera(s.ren->GetActiveCamera(), out + "/camera.json");
  WritePreset(tf, out + "/tf.json");
  std::ostringstream cmd;
  cmd.precision(17);
  cmd << "\"" << cli << "\" render \"" << data << "\" --array " << array << ":"
      << (st.component >= 0 ? std::to_string(st.component) : "mag") << " --tf \"" << out
      << "/tf.json\" --range " << range[0] << "," << range[1] << " --camera \"" << out
      << "/camera.json\" --size " << W << "x" << H << " --opacity-unit-distance " << unit
      << " --background 1,1,1 --error-tolerance " << st.tolerance << " --stats \"" << out
      << "/stats.json\" -o \"" << out << "/cli.png\"";
  if (st.supportRadius > 0)
  {
    cmd << " --support-radius " << st.supportRadius;
  }
  if (!st.kernel.empty())
  {
    cmd << " --kernel " << st.kernel;
  }
  if (!st.field.empty())
  {
    cmd << " --field " << st.field;
  }
  if (!st.field.empty() || st.shadows)
  {
    cmd << " --spp " << st.passes;
  }
  if (!st.classification.empty())
  {
    cmd << " --classification " << st.classification;
  }
  if (st.shadows)
  {
    cmd << " --shadows";
  }
  if (st.lod > 0)
  {
    cmd << " --lod " << st.lod;
  }
  for (size_t k = 0; k < st.radiusMap.size(); ++k)
  {
    cmd << (k == 0 ? " --radius-map " : ",") << st.radiusMap[k];
  }
  std::cout << cmd.str() << "\n";
  if (std::system(cmd.str().c_str()) != 0)
  {
    std::cerr << "FAIL: fluidcast render failed\n";
    return false;
  }
  p.cliSamples = StatsSamples(out + "/stats.json");
  vtkNew<vtkPNGReader> pr;
  pr->SetFileName((out + "/cli.png").c_str());
  pr->Update();
  p.cli = FromImageData(pr->GetOutput());
  if (p.cli.w != p.mapper.w || p.cli.h != p.mapper.h)
  {
    std::cerr << "FAIL: sizes differ\n";
    return false;
  }
  const size_t drawn = Drawn(p.mapper);
  if (drawn < static_cast<size_t>(W * H / 20))
  {
    std::cerr << "FAIL: the mapper drew almost nothing (" << drawn << " pixels)\n";
    return false;
  }
  return true;
}

int Window(const std::string& data, const std::string& array, const std::string& out,
  const std::string& cli, const std::string& tolerance)
{
  if (!Exists(data))
  {
    return MissingData(data);
  }
  auto ug = Read(data);
  Settings st;
  st.tolerance = tolerance;
  Pair p;
  if (!RenderPair(ug, data, array, out, cli, st, p))
  {
    return 1;
  }
  Diff d = Compare(p.mapper, p.cli);
  std::cout << "mapper vs CLI: max abs " << d.max << "/255, mean " << d.mean << "/255, "
            << d.above2 << " channels above 2/255; allowed: " << st.Allowed() << "/255\n";
  return d.max <= st.Allowed() ? 0 : 1;
}

/**
 * Each property set away from its default changes the image, and the mapper follows it as
 * the CLI's matching option does: the mapper agrees with the CLI render that uses the same
 * non-default value, and that CLI render differs from the mapper's default image by more
 * than the agreement allows (so a mapper that ignored the property would fail). The error
 * tolerance is checked by its sample counts: at full rate (ErrorTolerance 0) and at E_I = 0.05
 * the mapper and the CLI composite exactly the same samples, and E_I = 0.05 fewer.
 */
int Properties(const std::string& data, const std::string& array, const std::string& out,
  const std::string& cli)
{
  if (!Exists(data))
  {
    return MissingData(data);
  }
  auto ug = Read(data);
  // Full rate (2/255 agreement) except where the tolerance itself is tested: the kernel's
  // shape moves this smooth field's image by only 5/255.
  Settings base;
  base.tolerance = "off";
  Pair def;
  if (!RenderPair(ug, data, array, out + "/default", cli, base, def))
  {
    return 1;
  }
  int failures = 0;
  auto check = [&](const std::string& name, const Settings& st) -> Pair
  {
    Pair p;
    if (!RenderPair(ug, data, array, out + "/" + name, cli, st, p))
    {
      ++failures;
      return p;
    }
    const Diff agree = Compare(p.mapper, p.cli);
    const Diff moved = Compare(def.mapper, p.cli);
    std::cout << name << ": mapper vs CLI max " << agree.max << "/255 (allowed "
              << st.Allowed() << "); default mapper vs this CLI max " << moved.max << "/255\n";
    if (agree.max > st.Allowed())
    {
      std::cerr << "FAIL: " << name << ": the mapper does not follow the CLI\n";
      ++failures;
    }
    if (moved.max <= st.Allowed())
    {
      std::cerr << "FAIL: " << name << ": the setting does not change the image enough to test\n";
      ++failures;
    }
    return p;
  };
  Settings radius = base;
  radius.supportRadius = 1.6 * def.maxRadius;
  check("support_radius", radius);
  Settings kernel = base;
  kernel.kernel = "gaussian";
  check("kernel", kernel);
  Settings component = base;
  component.component = 2;
  check("vector_component", component);
  // Particle level of detail: the same cut of the view as the CLI's --lod.
  Settings lod = base;
  lod.lod = 12;
  check("lod", lod);
  // The RBF field (Morrical et al. 2023) and its options; 8 still renders accumulate the
  // passes the CLI's --spp 8 averages (the same passes: same offsets).
  Settings rbf = base;
  rbf.field = "rbf";
  rbf.passes = 8;
  const Pair post = check("rbf", rbf);
  Settings pre = rbf;
  pre.classification = "pre";
  const Pair prePair = check("rbf_pre", pre);
  {
    // The radius map: the fastest particles at half radius. Against the RBF image too.
    Settings map = rbf;
    map.radiusMap = { 0, 1, 1, 0.5 };
    const Pair mp = check("rbf_radius_map", map);
    const Diff moved = Compare(post.mapper, mp.cli);
    std::cout << "rbf_radius_map: unmapped mapper vs this CLI max " << moved.max << "/255\n";
    if (moved.max <= 2)
    {
      std::cerr << "FAIL: rbf_radius_map: the radius map does not change the image\n";
      ++failures;
    }
  }
  // Against the RBF image too: a mapper that ignored RBFClassification would draw `post`.
  const Diff preMoved = Compare(post.mapper, prePair.cli);
  std::cout << "rbf_pre: post mapper vs pre CLI max " << preMoved.max << "/255\n";
  if (preMoved.max <= 2)
  {
    std::cerr << "FAIL: rbf_pre: pre-classification does not change the image\n";
    ++failures;
  }
  // Shadows: one shade point a pass, chosen by accumulated opacity, so a pixel whose opacity
  // differs by a rounding between VTK's sampled tables and the CLI's nodes may pick another
  // point in a pass: at most 0.5 % of the channels beyond 2/255. Each against the CLI's
  // --shadows and unlike the unlit image `unlit`.
  auto checkLit = [&](const std::string& name, Settings lit, const Image& unlit)
  {
    lit.shadows = true;
    lit.passes = 8;
    Pair p;
    if (!RenderPair(ug, data, array, out + "/" + name, cli, lit, p))
    {
      ++failures;
      return;
    }
    const Diff agree = Compare(p.mapper, p.cli);
    const Diff moved = Compare(unlit, p.cli);
    const size_t channels = static_cast<size_t>(3) * p.mapper.w * p.mapper.h;
    std::cout << name << ": mapper vs CLI max " << agree.max << "/255, " << agree.above2
              << " channels above 2/255 of " << channels << "; unlit mapper vs this CLI max "
              << moved.max << "/255\n";
    if (agree.above2 * 200 > channels || moved.max <= 2)
    {
      std::cerr << "FAIL: " << name << ": the mapper does not follow the CLI\n";
      ++failures;
    }
  };
  checkLit("rbf_shadows", rbf, post.mapper);
  // Shadows on the SPH field (the CSPH field, marched stochastically).
  checkLit("sph_shadows", base, def.mapper);
  Settings coarse;
  coarse.tolerance = "0.05";
  Pair p1;
  const bool ok = RenderPair(ug, data, array, out + "/tolerance_0.05", cli, coarse, p1);
  std::cout << "samples: off mapper " << def.mapperSamples << ", CLI " << def.cliSamples
            << "; E_I 0.05 mapper " << p1.mapperSamples << ", CLI " << p1.cliSamples << "\n";
  if (!ok || def.mapperSamples != def.cliSamples || p1.mapperSamples != p1.cliSamples ||
    p1.mapperSamples >= def.mapperSamples)
  {
    std::cerr << "FAIL: ErrorTolerance does not set the samples as --error-tolerance does\n";
    ++failures;
  }
  return failures ? 1 : 0;
}

int Depth(const std::string& data, const std::string& array, const std::string& out)
{
  if (!Exists(data))
  {
    return MissingData(data);
  }
  auto ug = Read(data);
  double range[2];
  ug->GetPointData()->GetArray(array.c_str())->GetRange(range, -1);
  TF tf = MakeTF(range[0], range[1]);

  Scene s;
  s.Show(ug, array, Property(tf, 0.05));
  double b[6];
  s.mapper->GetBounds(b);
  // Look down -z so "in front" and "behind" are z ranges; a parallel projection gives the
  // box the same footprint at every depth.
  s.ren->GetActiveCamera()->ParallelProjectionOn();
  s.ren->ResetCamera(b);

  auto render = [&](double bg) {
    s.ren->SetBackground(bg, bg, bg);
    s.ren->ResetCameraClippingRange(b[0] - 1, b[1] + 1, b[2] - 1, b[3] + 1, b[4] - 1, b[5] + 1);
    s.win->Render();
    return Grab(s.win);
  };
  Image black = render(0), white = render(1);

  // An unlit red box covering the middle of the view, at a chosen z range.
  vtkNew<vtkCubeSource> cube;
  vtkActor* box = AddBox(s, cube);
  box->GetProperty()->SetColor(1, 0, 0);
  const double cx = 0.5 * (b[0] + b[1]), cy = 0.5 * (b[2] + b[3]);
  const double dx = 0.3 * (b[1] - b[0]), dy = 0.3 * (b[3] - b[2]);
  auto place = [&](double z0, double z1) {
    cube->SetBounds(cx - dx, cx + dx, cy - dy, cy + dy, z0, z1);
  };
  const double zmid = 0.5 * (b[4] + b[5]), zext = b[5] - b[4];
  place(b[5] + 0.05 * zext, b[5] + 0.1 * zext); // in front (camera looks down -z from +z)
  Image front = render(0);
  place(b[4] - 0.1 * zext, b[4] - 0.05 * zext); // behind
  Image behind = render(0);
  place(b[4] - 0.1 * zext, zmid); // from behind to the middle
  Image cut = render(0);
  WritePng(front, out + "/depth_front.png");
  WritePng(behind, out + "/depth_behind.png");
  WritePng(cut, out + "/depth_cut.png");
  WritePng(black, out + "/depth_none.png");
  WritePng(white, out + "/depth_none_white.png");

  // Pixels inside the box's footprint where the particles are clearly visible.
  double p0[4] = { cx - dx, cy - dy, b[5], 1 }, p1[4] = { cx + dx, cy + dy, b[5], 1 };
  s.ren->SetWorldPoint(p0);
  s.ren->WorldToDisplay();
  double d0[3];
  s.ren->GetDisplayPoint(d0);
  s.ren->SetWorldPoint(p1);
  s.ren->WorldToDisplay();
  double d1[3];
  s.ren->GetDisplayPoint(d1);
  size_t n = 0, frontBad = 0, behindBad = 0, cutHidden = 0, cutAsBehind = 0;
  for (int j = int(std::ceil(std::min(d0[1], d1[1]))) + 2; j < int(std::max(d0[1], d1[1])) - 2;
       ++j)
  {
    for (int i = int(std::ceil(std::min(d0[0], d1[0]))) + 2; i < int(std::max(d0[0], d1[0])) - 2;
         ++i)
    {
      if (i < 0 || j < 0 || i >= W || j >= H)
      {
        continue;
      }
      // alpha from the black/white pair: white - black = (1 - alpha) * 255.
      const double alpha = 1.0 - (white.at(i, j, 1) - black.at(i, j, 1)) / 255.0;
      if (alpha < 0.3)
      {
        continue;
      }
      ++n;
      // In front: exactly the box colour.
      frontBad += front.at(i, j, 0) != 255 || front.at(i, j, 1) != 0 || front.at(i, j, 2) != 0;
      // Behind: the particles over the box, P + (1 - alpha) * red.
      for (int c = 0; c < 3; ++c)
      {
        const double want = black.at(i, j, c) + (c == 0 ? (1 - alpha) * 255 : 0);
        behindBad += std::abs(behind.at(i, j, c) - want) > 3;
      }
      // Cutting: the half of the particles behind the box face is hidden, so the pixel is
      // neither the box nor the "behind" composite.
      cutHidden += cut.at(i, j, 0) == 255 && cut.at(i, j, 1) == 0 && cut.at(i, j, 2) == 0;
      int diff = 0;
      for (int c = 0; c < 3; ++c)
      {
        diff = std::max(diff, std::abs(cut.at(i, j, c) - behind.at(i, j, c)));
      }
      cutAsBehind += diff <= 3;
    }
  }
  std::cout << n << " covered pixels in the box footprint; box in front: " << frontBad
            << " not the box colour; behind: " << behindBad
            << " channels off P + (1 - a) B by more than 3/255; cutting: " << cutHidden
            << " show only the box, " << cutAsBehind << " look as if it were behind\n";
  if (n < 200)
  {
    std::cerr << "FAIL: too few covered pixels to judge\n";
    return 1;
  }
  const bool ok = frontBad == 0 && behindBad <= n / 100 && cutHidden < n / 2 && cutAsBehind < n / 2;
  return ok ? 0 : 1;
}

/**
 * Perspective depth-buffer unprojection against a closed form: a uniform slab of particles
 * (constant value, so constant opacity) seen face-on from a perspective camera, with an opaque
 * box from behind the slab up to z_c. The mapper must stop each ray where the box's depth
 * buffer says, so the slab's opacity in front of the box is 1 - exp(-sigma L), with L the
 * ray's path from the slab's top (z = 0.4) down to z_c: (0.4 - z_c) / cos(theta) for the
 * pixel's ray angle theta, computed here from the view angle alone. The opacity is measured
 * as (white box - black box) / 255 = 1 - alpha. Three cuts; within 0.03 (a sample step's
 * opacity).
 */
int DepthCut(const std::string& out)
{
  const double spacing = 0.05, h = 0.2, alpha0 = 0.5, unit = 0.2;
  vtkNew<vtkPoints> pts;
  for (int k = 0; k < 5; ++k)
  {
    for (int j = -20; j <= 20; ++j)
    {
      for (int i = -20; i <= 20; ++i)
      {
        pts->InsertNextPoint(i * spacing, j * spacing, k * spacing);
      }
    }
  }
  vtkNew<vtkPolyData> slab;
  slab->SetPoints(pts);
  vtkNew<vtkFloatArray> value;
  value->SetName("value");
  value->SetNumberOfTuples(pts->GetNumberOfPoints());
  value->Fill(0.5);
  slab->GetPointData()->AddArray(value);
  TF tf = MakeTF(0, 1);
  tf.opacity = { 0, alpha0, 1, alpha0 };
  const double sigma = -std::log(1 - alpha0) / unit;

  Scene s;
  s.Show(slab, "value", Property(tf, unit));
  s.mapper->SetSupportRadius(h);
  s.mapper->SetErrorTolerance(0);
  vtkCamera* cam = s.ren->GetActiveCamera();
  cam->SetPosition(0, 0, 3);
  cam->SetFocalPoint(0, 0, 0);
  cam->SetViewUp(0, 1, 0);
  cam->SetViewAngle(30);
  s.ren->ResetCameraClippingRange(-1.5, 1.5, -1.5, 1.5, -1, 0.5);

  vtkNew<vtkCubeSource> cube;
  vtkActor* box = AddBox(s, cube);
  const double top = 4 * spacing + h, tanHalf = std::tan(vtkMath::RadiansFromDegrees(15.0));
  double worst = 0;
  size_t n = 0;
  for (double zc : { 0.3, 0.15, 0.0 })
  {
    cube->SetBounds(-0.6, 0.6, -0.6, 0.6, -1.0, zc);
    Image img[2];
    for (int c = 0; c < 2; ++c)
    {
      box->GetProperty()->SetColor(c, c, c);
      s.ren->SetBackground(c, c, c);
      s.win->Render();
      img[c] = Grab(s.win);
    }
    WritePng(img[1], out + "/cut_" + std::to_string(zc) + ".png");
    for (int j = 0; j < H; ++j)
    {
      for (int i = 0; i < W; ++i)
      {
        // The pixel's ray: tangents of its angles from the view axis (rows bottom first).
        const double ty = (2.0 * (j + 0.5) / H - 1) * tanHalf;
        const double tx = (2.0 * (i + 0.5) / W - 1) * tanHalf * W / H;
        if (std::abs(tx) > 0.12 || std::abs(ty) > 0.12)
        {
          continue; // well inside the box's footprint at every cut
        }
        const double path = (top - zc) * std::sqrt(1 + tx * tx + ty * ty);
        const double want = 1 - std::exp(-sigma * path);
        const double got = 1 - (img[1].at(i, j, 1) - img[0].at(i, j, 1)) / 255.0;
        worst = std::max(worst, std::abs(got - want));
        ++n;
      }
    }
  }
  std::cout << n << " pixels at three cuts; largest opacity difference from the closed form "
            << worst << "\n";
  if (n < 1000 || worst > 0.03)
  {
    std::cerr << "FAIL: the slab in front of the box is not 1 - exp(-sigma L)\n";
    return 1;
  }
  return 0;
}

struct ErrorCatcher
{
  std::vector<std::string> messages;
  static void Callback(vtkObject*, unsigned long, void* self, void* data)
  {
    static_cast<ErrorCatcher*>(self)->messages.emplace_back(static_cast<const char*>(data));
  }
};

int Bad(const std::string& data)
{
  if (!Exists(data))
  {
    return MissingData(data);
  }
  auto ug = Read(data);
  int failures = 0;
  auto expect = [&](const char* what, vtkPointSet* input, const char* array, const char* radius,
                  const char* needle) {
    Scene s;
    ErrorCatcher catcher;
    vtkNew<vtkCallbackCommand> cb;
    cb->SetCallback(ErrorCatcher::Callback);
    cb->SetClientData(&catcher);
    s.mapper->AddObserver(vtkCommand::ErrorEvent, cb);
    s.mapper->SetInputData(input);
    s.mapper->SelectScalarArray(array);
    s.mapper->SetScalarModeToUsePointFieldData();
    if (radius)
    {
      s.mapper->SetRadiusArray(radius);
    }
    s.volume->SetProperty(Property(MakeTF(0, 1), 0.1));
    s.ren->SetBackground(1, 1, 1);
    s.ren->ResetCamera(-1, 1, -1, 1, -1, 1);
    s.win->Render();
    Image img = Grab(s.win);
    const bool blank =
      std::all_of(img.rgb.begin(), img.rgb.end(), [](unsigned char v) { return v == 255; });
    bool found = false;
    for (auto& m : catcher.messages)
    {
      found |= m.find(needle) != std::string::npos;
    }
    std::cout << what << ": " << (catcher.messages.empty() ? "(no error)" : catcher.messages[0])
              << "\n";
    if (!found || !blank)
    {
      std::cerr << "FAIL: " << what << ": expected an error containing '" << needle << "'"
                << (blank ? "" : " and nothing drawn") << "\n";
      ++failures;
    }
  };
  expect("missing array", ug, "no_such_array", nullptr, "no_such_array");
  vtkNew<vtkPolyData> empty;
  vtkNew<vtkPoints> none;
  empty->SetPoints(none);
  expect("no points", empty, "density", nullptr, "no points");

  vtkNew<vtkUnstructuredGrid> nanRadius;
  nanRadius->ShallowCopy(ug);
  vtkNew<vtkFloatArray> h;
  h->SetName("h");
  h->SetNumberOfTuples(ug->GetNumberOfPoints());
  h->Fill(std::nan(""));
  nanRadius->GetPointData()->AddArray(h);
  nanRadius->GetFieldData()->Initialize(); // no support_radius fallback
  expect("NaN radius", nanRadius, "density", "h", "NaN");

  vtkNew<vtkUnstructuredGrid> nanPoints;
  nanPoints->DeepCopy(ug);
  for (vtkIdType i = 0; i < nanPoints->GetNumberOfPoints(); ++i)
  {
    nanPoints->GetPoints()->SetPoint(i, std::nan(""), 0, 0);
  }
  expect("NaN coordinates", nanPoints, "density", nullptr, "NaN");
  return failures == 0 ? 0 : 1;
}
} // namespace

/**
 * The mapper's Backend: the same scene in the same window on the CPU and on the GPU (any
 * adapter; Mesa's lavapipe on CI) within 2/255, the device kept between frames, and Auto on
 * the CPU unless a hardware GPU is listed.
 */
int Backends(const std::string& data, const std::string& array, const std::string& out)
{
  if (!Exists(data))
  {
    std::cerr << "FAIL: " << data << " not present\n";
    return 1;
  }
  auto ug = Read(data);
  double range[2];
  ug->GetPointData()->GetArray(array.c_str())->GetRange(range, -1);
  Scene s;
  s.ren->SetBackground(1, 1, 1);
  s.Show(ug, array, Property(MakeTF(range[0], range[1]), 0.1));
  double b[6];
  s.mapper->GetBounds(b);
  SetupCamera(s, b);
  const char* names[] = { "auto", "cpu", "gpu" };
  for (int k = vtkFluidCastVolumeMapper::AUTO; k <= vtkFluidCastVolumeMapper::GPU; ++k)
  {
    s.mapper->SetBackend(k);
    if (s.mapper->GetBackendAsString() != names[k])
    {
      std::cerr << "FAIL: backend " << k << " is named " << s.mapper->GetBackendAsString() << "\n";
      return 1;
    }
  }
  s.mapper->SetBackendToCPU();
  s.win->Render();
  Image cpu = Grab(s.win);
  const std::string cpuDevice = s.mapper->GetLastDevice();
  s.mapper->SetBackendToGPU();
  s.win->Render();
  Image gpu = Grab(s.win);
  const std::string gpuDevice = s.mapper->GetLastDevice();
  WritePng(cpu, out + "/cpu.png");
  WritePng(gpu, out + "/gpu.png");
  s.win->Render(); // a second GPU frame, on the device kept from the first
  s.mapper->SetBackendToAuto();
  s.win->Render();
  const std::string autoDevice = s.mapper->GetLastDevice();
  std::cout << "CPU: " << cpuDevice << "; GPU: " << gpuDevice << "; Auto: " << autoDevice << "\n";
  if (cpuDevice.rfind("CPU", 0) != 0 || gpuDevice.rfind("GPU: ", 0) != 0)
  {
    std::cerr << "FAIL: the frames did not render where asked\n";
    return 1;
  }
  const bool software = gpuDevice.find("software") != std::string::npos;
  if (software && autoDevice.rfind("CPU", 0) != 0)
  {
    std::cerr << "FAIL: Auto took the software driver\n";
    return 1;
  }
  Diff d = Compare(cpu, gpu);
  const size_t drawn = Drawn(cpu);
  std::cout << "GPU vs CPU in a VTK window: max abs " << d.max << "/255, mean " << d.mean
            << "/255; " << drawn << " pixels drawn\n";
  if (drawn < static_cast<size_t>(W * H / 20))
  {
    std::cerr << "FAIL: the mapper drew almost nothing\n";
    return 1;
  }
  return d.max <= 2 ? 0 : 1;
}

int main(int argc, char* argv[])
{
  const std::string mode = argc > 1 ? argv[1] : "";
  if (mode == "window" && argc == 7)
  {
    return Window(argv[2], argv[3], argv[4], argv[5], argv[6]);
  }
  if (mode == "properties" && argc == 6)
  {
    return Properties(argv[2], argv[3], argv[4], argv[5]);
  }
  if (mode == "depthcut" && argc == 3)
  {
    return DepthCut(argv[2]);
  }
  if (mode == "depth" && argc == 5)
  {
    return Depth(argv[2], argv[3], argv[4]);
  }
  if (mode == "bad" && argc == 3)
  {
    return Bad(argv[2]);
  }
  if (mode == "backend" && argc == 5)
  {
    return Backends(argv[2], argv[3], argv[4]);
  }
  std::cerr << "usage: TestFluidCastMapper window DATA ARRAY OUTDIR CLI TOLERANCE | properties "
               "DATA ARRAY OUTDIR CLI | depth DATA ARRAY OUTDIR | depthcut OUTDIR | bad DATA | backend DATA ARRAY "
               "OUTDIR\n";
  return 2;
}
