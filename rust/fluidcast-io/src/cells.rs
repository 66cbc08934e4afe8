//! What a file holds besides its particles: its cells and cell data.
//!
//! fluidcast keeps points, point data and field data; every point is a particle. A file of
//! particles has no cells, or one vertex (or poly-vertex) cell per particle, and no cell
//! data. A mesh (tetrahedra, polygons, lines) also has cells that join its points and,
//! often, values per cell: a reader that hands a file on as particles would drop them. The
//! readers record them in [`Cells`], and [`Cells::dropped`] says in words what a particle
//! read would lose, so that a front end which passes data on to other tools (the VTK and
//! ParaView reader) can refuse the file by name instead of changing it silently.

/// VTK's cell type ids of the cells that hold one or more points and nothing else.
const VTK_VERTEX: u8 = 1;
const VTK_POLY_VERTEX: u8 = 2;

/// The four cell arrays of poly data: XML `<Verts>`, `<Lines>`, `<Strips>`, `<Polys>`, legacy
/// `VERTICES`, `LINES`, `TRIANGLE_STRIPS`, `POLYGONS`.
#[derive(Debug, Clone, Copy)]
pub(crate) enum PolyCells {
    Verts,
    Lines,
    Strips,
    Polys,
}

/// The cells and cell data of one file (all its pieces).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Cells {
    /// Cells of every kind: vertices, lines, polygons, volume cells.
    pub count: u64,
    /// The cells that are not vertices or poly-vertices, by kind ("tetra", "polygons", …)
    /// with how many of each, in the order the file first has them.
    pub other: Vec<(String, u64)>,
    /// The names of the cell-data arrays (every piece's, each name once).
    pub cell_arrays: Vec<String>,
}

impl Cells {
    /// Counts `n` cells of kind `kind`, which a particle read keeps when `vertices`.
    pub fn add(&mut self, kind: &str, n: u64, vertices: bool) {
        self.count = self.count.saturating_add(n);
        if !vertices {
            self.add_other(kind, n);
        }
    }

    /// Counts `n` cells of poly data's array `kind` (vertices are kept by a particle read).
    pub(crate) fn add_poly(&mut self, kind: PolyCells, n: u64) {
        let (name, vertices) = match kind {
            PolyCells::Verts => ("vertices", true),
            PolyCells::Lines => ("lines", false),
            PolyCells::Strips => ("triangle strips", false),
            PolyCells::Polys => ("polygons", false),
        };
        self.add(name, n, vertices);
    }

    /// Adds `n` to the cells of `kind` that are not vertices (already in `count`).
    fn add_other(&mut self, kind: &str, n: u64) {
        if n == 0 {
            return;
        }
        match self.other.iter_mut().find(|(k, _)| k == kind) {
            Some((_, c)) => *c = c.saturating_add(n),
            None => self.other.push((kind.to_string(), n)),
        }
    }

    /// Counts cells by their VTK cell type ids (an unstructured grid's `types`).
    pub fn add_types(&mut self, types: impl IntoIterator<Item = f64>) {
        let mut tally = [0u64; 256];
        let mut order: Vec<u8> = Vec::new();
        for t in types {
            // A type id outside 0..=255 is not a VTK cell type; count it as such.
            #[allow(clippy::cast_possible_truncation)] // in 0..=255, checked
            let id = if (0.0..=255.0).contains(&t) {
                t as u8
            } else {
                0
            };
            if let Some(c) = tally.get_mut(usize::from(id)) {
                if *c == 0 {
                    order.push(id);
                }
                *c += 1;
            }
        }
        for id in order {
            let n = tally.get(usize::from(id)).copied().unwrap_or(0);
            let vertices = id == VTK_VERTEX || id == VTK_POLY_VERTEX;
            self.add(&cell_type_name(id), n, vertices);
        }
    }

    /// Records a cell-data array's name.
    pub fn add_array(&mut self, name: &str) {
        if !self.cell_arrays.iter().any(|n| n == name) {
            self.cell_arrays.push(name.to_string());
        }
    }

    /// Adds another piece's cells.
    pub fn merge(&mut self, other: &Cells) {
        self.count = self.count.saturating_add(other.count);
        for (kind, n) in &other.other {
            self.add_other(kind, *n);
        }
        for name in &other.cell_arrays {
            self.add_array(name);
        }
    }

    /// Whether a particle read keeps everything: no cells but vertices, no cell data.
    pub fn only_vertices(&self) -> bool {
        self.other.is_empty() && self.cell_arrays.is_empty()
    }

    /// What a particle read drops, in words ("1063 cells that are not vertices (1063
    /// tetra) and 2 cell-data arrays (pressure, id)"); `None` when it drops nothing.
    pub fn dropped(&self) -> Option<String> {
        let mut parts = Vec::new();
        if !self.other.is_empty() {
            let n: u64 = self.other.iter().map(|(_, c)| c).sum();
            let kinds: Vec<String> = self.other.iter().map(|(k, c)| format!("{c} {k}")).collect();
            parts.push(format!(
                "{n} cell{} that {} not vertices ({})",
                plural(n),
                if n == 1 { "is" } else { "are" },
                kinds.join(", ")
            ));
        }
        if !self.cell_arrays.is_empty() {
            let n = self.cell_arrays.len() as u64;
            parts.push(format!(
                "{n} cell-data array{} ({})",
                plural(n),
                self.cell_arrays.join(", ")
            ));
        }
        (!parts.is_empty()).then(|| parts.join(" and "))
    }
}

fn plural(n: u64) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// The name of a VTK cell type id (`vtkCellType.h`), for messages.
pub fn cell_type_name(id: u8) -> String {
    let name = match id {
        0 => "empty cells",
        1 => "vertex",
        2 => "poly-vertex",
        3 => "line",
        4 => "poly-line",
        5 => "triangle",
        6 => "triangle strip",
        7 => "polygon",
        8 => "pixel",
        9 => "quad",
        10 => "tetra",
        11 => "voxel",
        12 => "hexahedron",
        13 => "wedge",
        14 => "pyramid",
        15 => "pentagonal prism",
        16 => "hexagonal prism",
        21 => "quadratic edge",
        22 => "quadratic triangle",
        23 => "quadratic quad",
        24 => "quadratic tetra",
        25 => "quadratic hexahedron",
        42 => "polyhedron",
        _ => return format!("cell type {id}"),
    };
    name.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertices_and_poly_vertices_are_particles() {
        let mut c = Cells::default();
        c.add_types([1.0, 1.0, 2.0]);
        assert_eq!(c.count, 3);
        assert!(c.only_vertices());
        assert_eq!(c.dropped(), None);
    }

    #[test]
    fn other_cells_and_cell_data_are_named_with_counts() {
        let mut c = Cells::default();
        c.add_types([10.0, 1.0, 10.0, 5.0, 300.0]);
        c.add_array("pressure");
        c.add_array("pressure");
        assert_eq!(c.count, 5);
        assert!(!c.only_vertices());
        assert_eq!(
            c.dropped().as_deref(),
            Some(
                "4 cells that are not vertices (2 tetra, 1 triangle, 1 empty cells) and 1 \
                 cell-data array (pressure)"
            )
        );
    }

    #[test]
    fn cell_data_alone_is_dropped_too() {
        let mut c = Cells::default();
        c.add("vertices", 4, true);
        assert!(c.only_vertices());
        c.add_array("id");
        assert!(!c.only_vertices());
        assert_eq!(c.dropped().as_deref(), Some("1 cell-data array (id)"));
    }

    /// Every name against VTK's class for that id (`vtkCellType.h`, `vtkCellTypes`), spaces
    /// and hyphens dropped: a name that a test of its own would only repeat.
    #[test]
    fn cell_type_names_are_vtks() {
        let vtk = [
            (1, "Vertex"),
            (2, "PolyVertex"),
            (3, "Line"),
            (4, "PolyLine"),
            (5, "Triangle"),
            (6, "TriangleStrip"),
            (7, "Polygon"),
            (8, "Pixel"),
            (9, "Quad"),
            (10, "Tetra"),
            (11, "Voxel"),
            (12, "Hexahedron"),
            (13, "Wedge"),
            (14, "Pyramid"),
            (15, "PentagonalPrism"),
            (16, "HexagonalPrism"),
            (21, "QuadraticEdge"),
            (22, "QuadraticTriangle"),
            (23, "QuadraticQuad"),
            (24, "QuadraticTetra"),
            (25, "QuadraticHexahedron"),
            (42, "Polyhedron"),
        ];
        for (id, class) in vtk {
            let ours: String = cell_type_name(id)
                .split([' ', '-'])
                .map(|w| {
                    let mut c = w.chars();
                    c.next()
                        .map_or(String::new(), |f| f.to_uppercase().chain(c).collect())
                })
                .collect();
            assert_eq!(ours, class, "cell type {id}");
        }
        assert_eq!(cell_type_name(0), "empty cells");
        assert_eq!(cell_type_name(200), "cell type 200");
    }

    #[test]
    fn merge_adds_counts_kinds_and_names() {
        let mut a = Cells::default();
        a.add("polygons", 3, false);
        a.add("vertices", 2, true);
        let mut b = Cells::default();
        b.add("polygons", 4, false);
        b.add("lines", 1, false);
        b.add_array("n");
        a.merge(&b);
        assert_eq!(a.count, 10);
        assert_eq!(
            a.other,
            vec![("polygons".to_string(), 7), ("lines".to_string(), 1)]
        );
        assert_eq!(a.cell_arrays, vec!["n".to_string()]);
    }
}
