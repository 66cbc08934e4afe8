//! A render reports its progress and stops when asked (`RenderParams::progress`): the
//! adaptive renderer by bundles, the reference ray caster by screen tiles.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

mod common;
use std::sync::Arc;

use common::{cloud, cloud_view};
use fluidcast_render::{render_adaptive, render_reference, Progress, RenderError, RenderParams};
use fluidcast_sph::FieldKind;

fn params(progress: &Arc<Progress>) -> RenderParams {
    RenderParams {
        width: 96,
        height: 64,
        progress: Some(progress.clone()),
        ..Default::default()
    }
}

#[test]
fn a_finished_render_is_all_done_and_a_cancelled_one_says_so() {
    let p = cloud(300, 5);
    let (cam, tf) = cloud_view(30.0, 20.0, false, FieldKind::Csph);
    let done = Arc::new(Progress::default());
    assert_eq!(done.fraction(), 0.0);
    render_adaptive(&p, None, &cam, &tf, &params(&done)).unwrap();
    assert_eq!(done.fraction(), 1.0);
    let done = Arc::new(Progress::default());
    render_reference(&p, &cam, &tf, &params(&done)).unwrap();
    assert_eq!(done.fraction(), 1.0);

    let stop = Arc::new(Progress::default());
    stop.cancel();
    let e = render_adaptive(&p, None, &cam, &tf, &params(&stop))
        .err()
        .unwrap();
    assert!(matches!(e, RenderError::Cancelled), "{e}");
    let e = render_reference(&p, &cam, &tf, &params(&stop))
        .err()
        .unwrap();
    assert!(matches!(e, RenderError::Cancelled), "{e}");
}
