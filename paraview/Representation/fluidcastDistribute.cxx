#include "fluidcastDistribute.h"

#include "vtkAppendPolyData.h"
#include "vtkCommunicator.h"
#include "vtkDataArray.h"
#include "vtkDataSetAttributes.h"
#include "vtkDoubleArray.h"
#include "vtkFieldData.h"
#include "vtkFluidCastVolumeMapper.h"
#include "vtkIdList.h"
#include "vtkMultiProcessController.h"
#include "vtkNew.h"
#include "vtkPointData.h"
#include "vtkPointSet.h"
#include "vtkPoints.h"
#include "vtkPolyData.h"
#include "vtkUnsignedCharArray.h"

#include <algorithm>
#include <cmath>
#include <array>
#include <cstring>
#include <limits>
#include <sstream>
#include <vector>

namespace fluidcast_paraview
{
namespace
{
using Point = std::array<double, 3>;

/** Points per rank that shape the kd-tree (all ranks see the same sample). */
constexpr vtkIdType kSamplesPerRank = 4096;

/** Ids of the input points that this piece owns (not DUPLICATEPOINT ghosts). */
std::vector<vtkIdType> OwnedIds(vtkPointSet* input)
{
  const vtkIdType n = input ? input->GetNumberOfPoints() : 0;
  vtkUnsignedCharArray* ghosts = input ? input->GetPointData()->GetGhostArray() : nullptr;
  std::vector<vtkIdType> ids;
  ids.reserve(static_cast<size_t>(n));
  for (vtkIdType i = 0; i < n; ++i)
  {
    if (!ghosts || !(ghosts->GetValue(i) & vtkDataSetAttributes::DUPLICATEPOINT))
    {
      ids.push_back(i);
    }
  }
  return ids;
}

/** A point set with `ids` of `input` and their point arrays (vtkGhostType left out). */
vtkSmartPointer<vtkPolyData> Subset(vtkPointSet* input, const std::vector<vtkIdType>& ids)
{
  auto out = vtkSmartPointer<vtkPolyData>::New();
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  pts->SetNumberOfPoints(static_cast<vtkIdType>(ids.size()));
  vtkNew<vtkPointData> in;
  in->ShallowCopy(input->GetPointData());
  in->RemoveArray(vtkDataSetAttributes::GhostArrayName());
  vtkPointData* pd = out->GetPointData();
  pd->CopyAllocate(in, static_cast<vtkIdType>(ids.size()));
  for (size_t k = 0; k < ids.size(); ++k)
  {
    pts->SetPoint(static_cast<vtkIdType>(k), input->GetPoint(ids[k]));
    pd->CopyData(in, ids[k], static_cast<vtkIdType>(k));
  }
  out->SetPoints(pts);
  return out;
}

/** Global min and max of each coordinate over the finite points of `ids` of every rank
 * (invalid box: none). A point with an infinite or NaN coordinate is left out, as the renderer
 * leaves it out: the box ParaView composites by stays finite. */
vtkBoundingBox GlobalBounds(
  vtkPointSet* input, const std::vector<vtkIdType>& ids, vtkMultiProcessController* c)
{
  const double inf = std::numeric_limits<double>::infinity();
  double local[6] = { inf, inf, inf, inf, inf, inf }; // min x y z, -max x y z
  for (vtkIdType i : ids)
  {
    const double* x = input->GetPoint(i);
    if (!(std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2])))
    {
      continue;
    }
    for (int k = 0; k < 3; ++k)
    {
      local[k] = std::min(local[k], x[k]);
      local[3 + k] = std::min(local[3 + k], -x[k]);
    }
  }
  double all[6];
  c->AllReduce(local, all, 6, vtkCommunicator::MIN_OP);
  vtkBoundingBox box;
  if (all[0] <= -all[3])
  {
    box.SetBounds(all[0], -all[3], all[1], -all[4], all[2], -all[5]);
  }
  return box;
}

double AllMax(vtkMultiProcessController* c, double v)
{
  double out = v;
  c->AllReduce(&v, &out, 1, vtkCommunicator::MAX_OP);
  return out;
}

/**
 * The support radius every rank uses, as the mapper would choose it for all particles at
 * once: SupportRadius; else the largest RadiusScale × RadiusArray; else the field data
 * "support_radius" of any piece; else the particle count-weighted mean of each piece's
 * spacing-based suggestion. `shared` is set to H when the ranks must be told it (field data
 * or spacing), else 0.
 */
double GlobalRadius(vtkPointSet* input, const std::vector<vtkIdType>& ids,
  vtkFluidCastVolumeMapper* mapper, vtkMultiProcessController* c, double& shared,
  std::string& note)
{
  shared = 0;
  if (mapper->GetSupportRadius() > 0)
  {
    note = "the SupportRadius property";
    return mapper->GetSupportRadius();
  }
  const char* name = mapper->GetRadiusArray();
  if (name && name[0])
  {
    double local = 0;
    vtkDataArray* a = input ? input->GetPointData()->GetArray(name) : nullptr;
    for (vtkIdType i : ids)
    {
      local = a ? std::max(local, a->GetComponent(i, 0)) : local;
    }
    note = std::string("the largest of RadiusScale x '") + name + "'";
    return AllMax(c, local * mapper->GetRadiusScale());
  }
  double field = -1;
  vtkDataArray* h = input ? input->GetFieldData()->GetArray("support_radius") : nullptr;
  if (h && h->GetNumberOfTuples() > 0)
  {
    field = h->GetComponent(0, 0);
  }
  field = AllMax(c, field);
  if (field > 0)
  {
    note = "the field data 'support_radius'";
    shared = field;
    return field;
  }
  // The spacing-based suggestion of this rank's own particles, weighted by their number.
  double local[2] = { 0, 0 }, all[2];
  if (!ids.empty())
  {
    vtkSmartPointer<vtkPolyData> own = Subset(input, ids);
    mapper->SetInputData(own);
    if (mapper->UpdateParticles())
    {
      local[0] = static_cast<double>(ids.size()) * mapper->GetLastMaxRadius();
      local[1] = static_cast<double>(ids.size());
    }
    mapper->SetInputData(nullptr);
  }
  c->AllReduce(local, all, 2, vtkCommunicator::SUM_OP);
  shared = all[1] > 0 ? all[0] / all[1] : 0;
  note = "2 x the mean particle spacing (each rank's estimate, weighted by its particles)";
  return shared;
}

/** Splits `box` among ranks [r0, r1) at sample quantiles along its longest axis. */
void Split(const vtkBoundingBox& box, std::vector<Point> samples, int r0, int r1,
  std::vector<vtkBoundingBox>& out)
{
  if (r1 - r0 == 1)
  {
    out[r0] = box;
    return;
  }
  const int axis = box.GetMaxLength() == box.GetLength(0) ? 0
    : box.GetMaxLength() == box.GetLength(1)             ? 1
                                                         : 2;
  const int left = (r1 - r0) / 2;
  const double lo = box.GetMinPoint()[axis], hi = box.GetMaxPoint()[axis];
  double cut = 0.5 * (lo + hi);
  if (!samples.empty())
  {
    const size_t m = samples.size() * left / (r1 - r0);
    std::nth_element(samples.begin(), samples.begin() + m, samples.end(),
      [axis](const Point& a, const Point& b) { return a[axis] < b[axis]; });
    cut = samples[m][axis];
    if (!(cut > lo && cut < hi))
    {
      cut = 0.5 * (lo + hi);
    }
  }
  double b[6];
  box.GetBounds(b);
  double lb[6], rb[6];
  std::copy(b, b + 6, lb);
  std::copy(b, b + 6, rb);
  lb[2 * axis + 1] = cut;
  rb[2 * axis] = cut;
  std::vector<Point> ls, rs;
  for (const Point& p : samples)
  {
    (p[axis] < cut ? ls : rs).push_back(p);
  }
  Split(vtkBoundingBox(lb), std::move(ls), r0, r0 + left, out);
  Split(vtkBoundingBox(rb), std::move(rs), r0 + left, r1, out);
}

/** One box per rank tiling `extent`, the same on every rank. */
std::vector<vtkBoundingBox> Regions(vtkPointSet* input, const std::vector<vtkIdType>& ids,
  const vtkBoundingBox& extent, vtkMultiProcessController* c)
{
  const int n = c->GetNumberOfProcesses();
  const vtkIdType stride = std::max<vtkIdType>(1, ids.size() / kSamplesPerRank);
  std::vector<double> mine;
  for (size_t k = 0; k < ids.size(); k += static_cast<size_t>(stride))
  {
    const double* x = input->GetPoint(ids[k]);
    mine.insert(mine.end(), x, x + 3);
  }
  std::vector<vtkIdType> lengths(n), offsets(n);
  vtkIdType len = static_cast<vtkIdType>(mine.size());
  c->AllGather(&len, lengths.data(), 1);
  vtkIdType total = 0;
  for (int r = 0; r < n; ++r)
  {
    offsets[r] = total;
    total += lengths[r];
  }
  std::vector<double> all(static_cast<size_t>(std::max<vtkIdType>(total, 1)));
  c->AllGatherV(mine.data(), all.data(), len, lengths.data(), offsets.data());
  std::vector<Point> samples(static_cast<size_t>(total / 3));
  for (size_t k = 0; k < samples.size(); ++k)
  {
    samples[k] = { all[3 * k], all[3 * k + 1], all[3 * k + 2] };
  }
  std::vector<vtkBoundingBox> boxes(n);
  Split(extent, std::move(samples), 0, n, boxes);
  return boxes;
}

/** Squared distance from `x` to `box` (0 inside). */
double Distance2(const vtkBoundingBox& box, const double x[3])
{
  double d2 = 0;
  for (int k = 0; k < 3; ++k)
  {
    const double d = std::max({ box.GetMinPoint()[k] - x[k], 0.0, x[k] - box.GetMaxPoint()[k] });
    d2 += d * d;
  }
  return d2;
}

/** What this rank sends to each rank: point ids and whether each is a halo copy there. */
struct Outgoing
{
  std::vector<std::vector<vtkIdType>> Ids;
  std::vector<std::vector<unsigned char>> Halo;
};

Outgoing Route(vtkPointSet* input, const std::vector<vtkIdType>& ids,
  const std::vector<vtkBoundingBox>& boxes, double halo)
{
  Outgoing o;
  o.Ids.resize(boxes.size());
  o.Halo.resize(boxes.size());
  for (vtkIdType i : ids)
  {
    const double* x = input->GetPoint(i);
    int owner = -1;
    for (size_t r = 0; r < boxes.size(); ++r)
    {
      if (owner < 0 && boxes[r].ContainsPoint(x))
      {
        owner = static_cast<int>(r);
      }
    }
    for (size_t r = 0; r < boxes.size(); ++r)
    {
      const bool own = static_cast<int>(r) == owner;
      if (own || Distance2(boxes[r], x) <= halo * halo)
      {
        o.Ids[r].push_back(i);
        o.Halo[r].push_back(own ? 0 : vtkDataSetAttributes::DUPLICATEPOINT);
      }
    }
  }
  return o;
}

/** Sends each rank its particles; returns what this rank received, merged. */
vtkSmartPointer<vtkPolyData> Exchange(
  vtkPointSet* input, const Outgoing& out, vtkMultiProcessController* c)
{
  const int n = c->GetNumberOfProcesses();
  vtkSmartPointer<vtkPolyData> mine;
  for (int root = 0; root < n; ++root)
  {
    vtkSmartPointer<vtkPolyData> piece = input ? Subset(input, out.Ids[root])
                                               : vtkSmartPointer<vtkPolyData>::New();
    vtkNew<vtkUnsignedCharArray> ghosts;
    ghosts->SetName(vtkDataSetAttributes::GhostArrayName());
    ghosts->SetNumberOfValues(static_cast<vtkIdType>(out.Halo[root].size()));
    std::copy(out.Halo[root].begin(), out.Halo[root].end(), ghosts->GetPointer(0));
    piece->GetPointData()->AddArray(ghosts);
    std::vector<vtkSmartPointer<vtkDataObject>> received;
    c->Gather(piece, received, root);
    if (root == c->GetLocalProcessId())
    {
      vtkNew<vtkAppendPolyData> append;
      for (auto& r : received)
      {
        vtkPolyData* pd = vtkPolyData::SafeDownCast(r);
        if (pd && pd->GetNumberOfPoints() > 0)
        {
          append->AddInputData(pd);
        }
      }
      mine = vtkSmartPointer<vtkPolyData>::New();
      if (append->GetNumberOfInputConnections(0) > 0)
      {
        append->Update();
        mine->ShallowCopy(append->GetOutput());
      }
    }
  }
  return mine;
}
}

//------------------------------------------------------------------------------
Partition Distribute(
  vtkPointSet* input, vtkFluidCastVolumeMapper* mapper, vtkMultiProcessController* c)
{
  Partition p;
  const std::vector<vtkIdType> ids = OwnedIds(input);
  double shared = 0;
  p.SupportRadius = GlobalRadius(input, ids, mapper, c, shared, p.RadiusNote);
  vtkBoundingBox extent = GlobalBounds(input, ids, c);
  if (!extent.IsValid())
  {
    p.Particles = vtkSmartPointer<vtkPolyData>::New();
    return p;
  }
  extent.Inflate(std::max(p.SupportRadius, 0.0));
  p.Extent = extent;
  const std::vector<vtkBoundingBox> boxes = Regions(input, ids, extent, c);
  p.Region = boxes[c->GetLocalProcessId()];
  p.Particles = Exchange(input, Route(input, ids, boxes, 2 * p.SupportRadius), c);
  if (input)
  {
    p.Particles->GetFieldData()->ShallowCopy(input->GetFieldData());
  }
  if (shared > 0)
  {
    vtkNew<vtkDoubleArray> h;
    h->SetName("support_radius");
    h->InsertNextValue(shared);
    p.Particles->GetFieldData()->AddArray(h);
  }
  vtkUnsignedCharArray* g = p.Particles->GetPointData()->GetGhostArray();
  for (vtkIdType i = 0; g && i < g->GetNumberOfValues(); ++i)
  {
    (g->GetValue(i) ? p.Halo : p.Owned)++;
  }
  return p;
}

//------------------------------------------------------------------------------
void CroppingPlanes(const vtkBoundingBox& region, const vtkBoundingBox& extent, double planes[6])
{
  constexpr double far = 1e30;
  double r[6], e[6];
  region.GetBounds(r);
  extent.GetBounds(e);
  for (int k = 0; k < 6; ++k)
  {
    planes[k] = r[k] == e[k] ? (k % 2 ? far : -far) : r[k];
  }
}

//------------------------------------------------------------------------------
vtkSmartPointer<vtkPointSet> WithoutHalo(vtkPointSet* data)
{
  vtkUnsignedCharArray* g = data ? data->GetPointData()->GetGhostArray() : nullptr;
  bool any = false;
  for (vtkIdType i = 0; g && !any && i < g->GetNumberOfValues(); ++i)
  {
    any = (g->GetValue(i) & vtkDataSetAttributes::DUPLICATEPOINT) != 0;
  }
  if (!any)
  {
    return data;
  }
  vtkSmartPointer<vtkPolyData> out = Subset(data, OwnedIds(data));
  out->GetFieldData()->ShallowCopy(data->GetFieldData());
  return out;
}
}
