/**
 * Particles across MPI ranks for the fluidcast representation.
 *
 * SPH sums at a point need every particle whose support reaches it, and ordered compositing
 * needs each rank to own a convex region of space. `Distribute` splits the field's extent
 * into one box per rank (a kd-tree over a sample of the particles, so each box holds about
 * the same number), sends every particle to the rank whose box holds it and, as a halo, to
 * every rank whose box lies within 2 H of it (H: the largest support radius; the second H
 * covers a sampling step that straddles a box face). Each rank then renders only the part
 * of the field inside its box (vtkFluidCastVolumeMapper's Cropping) and ParaView composites
 * the ranks' images in visibility order of the boxes.
 */
#ifndef fluidcastDistribute_h
#define fluidcastDistribute_h

#include "vtkBoundingBox.h"  // for vtkBoundingBox
#include "vtkSmartPointer.h" // for vtkSmartPointer

#include <string>

class vtkFluidCastVolumeMapper;
class vtkMultiProcessController;
class vtkPointSet;
class vtkPolyData;

namespace fluidcast_paraview
{
/** One rank's share. */
struct Partition
{
  /** The box this rank owns, world coordinates; the boxes of all ranks tile the field's
   * extent (the particles' bounds grown by H). Invalid when no rank has particles. */
  vtkBoundingBox Region;
  /** What the ranks' boxes tile: the particles' bounds grown by H, world coordinates. */
  vtkBoundingBox Extent;
  /** Owned and halo particles: points, the input's point arrays, its field data (with
   * "support_radius" set when the radius came from field data or the particle spacing, so
   * that every rank uses the same one) and vtkGhostType, DUPLICATEPOINT on halo particles. */
  vtkSmartPointer<vtkPolyData> Particles;
  vtkIdType Owned = 0;
  vtkIdType Halo = 0;
  /** The support radius H the halo was built for (world units). */
  double SupportRadius = 0;
  /** Where H came from, for the log. */
  std::string RadiusNote;
};

/**
 * Collective over `controller` (every rank must call it, with its own piece, possibly
 * empty). `mapper` is this rank's mapper with the representation's settings (support
 * radius, radius array, selected array): it tells how large H is. Input points flagged
 * DUPLICATEPOINT in vtkGhostType (copies owned by another piece) are dropped first.
 */
Partition Distribute(
  vtkPointSet* input, vtkFluidCastVolumeMapper* mapper, vtkMultiProcessController* controller);

/**
 * The box `region` of `extent` as cropping planes (xmin, xmax, ...) for the mapper: faces on
 * the extent's boundary move out to ±1e30, so that only the faces shared with other ranks
 * cut the rays. A sampling step that crosses a shared face is cut there on both sides and
 * the two parts add up to the whole step; at the outer boundary nothing is cut, as without
 * ranks (the last step of a ray may reach beyond the particles' supports).
 */
void CroppingPlanes(const vtkBoundingBox& region, const vtkBoundingBox& extent, double planes[6]);

/**
 * `data` without its points flagged DUPLICATEPOINT in vtkGhostType (halo particles, when
 * the pieces of all ranks are gathered onto one process), or `data` itself when it has none.
 */
vtkSmartPointer<vtkPointSet> WithoutHalo(vtkPointSet* data);
}

#endif
