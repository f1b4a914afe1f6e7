//! The hot paths do not allocate: counted with a global allocator (one test in this binary,
//! so no other test thread allocates meanwhile).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::Vector3;
use tagk_dynamics::{
    KinematicTree, QuadrotorModel, WindowBuilder, newton_euler, rigid_body_regressor,
    write_rigid_body_regressor,
};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System.alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations_in(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    f();
    ALLOCATIONS.load(Ordering::SeqCst) - before
}

#[test]
fn hot_paths_do_not_allocate() {
    let theta = QuadrotorModel::crazyflie_2_1().params;
    let (a, w, wd) = (
        Vector3::new(0.1, -0.2, 9.9),
        Vector3::new(0.3, 0.1, -0.2),
        Vector3::new(1.0, 2.0, -1.0),
    );
    let wrench = newton_euler(&theta, &a, &w, &wd);
    let mut buf = [0.0; 60];
    let mut window = WindowBuilder::new(5).unwrap();
    let mut a_out = vec![0.0; 300];
    let mut b_out = vec![0.0; 30];
    let n = allocations_in(|| {
        for _ in 0..20 {
            std::hint::black_box(rigid_body_regressor(&a, &w, &wd));
            write_rigid_body_regressor(&a, &w, &wd, &mut buf).unwrap();
            window.push(&a, &w, &wd, &wrench).unwrap();
            window.push_rows(&buf, &wrench.to_array()).unwrap();
            std::hint::black_box(window.stacked());
            window.build(&mut a_out, &mut b_out).unwrap();
        }
    });
    assert_eq!(n, 0, "rigid body / window allocated {n} times");

    let path = format!("{}/robots/panda.urdf", env!("CARGO_MANIFEST_DIR"));
    let chain = KinematicTree::from_urdf_file(path).unwrap();
    let dof = chain.dof();
    let params = chain.params();
    let mut ws = chain.workspace();
    let mut rows = vec![0.0; dof * chain.n_params()];
    let mut tau = vec![0.0; dof];
    let q = vec![0.2; dof];
    let n = allocations_in(|| {
        for _ in 0..5 {
            chain
                .joint_torque_regressor_into(&q, &q, &q, &mut ws, &mut rows)
                .unwrap();
            chain
                .rnea_into(&q, &q, &q, &params, &mut ws, &mut tau)
                .unwrap();
        }
    });
    assert_eq!(n, 0, "chain hot paths allocated {n} times");
    // The counter works: an allocating call is seen.
    assert!(allocations_in(|| drop(std::hint::black_box(chain.rnea(&q, &q, &q).unwrap()))) > 0);
}
