// gemm 0.19 (the crate candle and our fused layers call) against OpenBLAS 0.3.21 (Debian
// bookworm's libopenblas-dev), one thread each, at the GEMM shapes of the SMILe authors' SAC and
// discriminator steps. Build: a scratch crate with Cargo.toml.example and build.rs.example,
// this file as src/main.rs; `apt-get install libopenblas-dev`; `OPENBLAS_NUM_THREADS=1 taskset -c 0`.
use std::time::Instant;
extern "C" { fn cblas_sgemm(o:i32,ta:i32,tb:i32,m:i32,n:i32,k:i32,al:f32,a:*const f32,lda:i32,b:*const f32,ldb:i32,be:f32,c:*mut f32,ldc:i32); fn openblas_set_num_threads(n:i32); }
// C (m x n) = op(A) op(B); ta: A stored as (k x m) row-major if true
fn run(m:usize,n:usize,k:usize,ta:bool,tb:bool,blas:bool)->f64{
  let a=vec![0.5f32;m*k]; let b=vec![0.25f32;k*n]; let mut c=vec![0f32;m*n];
  let (ars,acs)= if ta {(1isize,m as isize)} else {(k as isize,1)};
  let (brs,bcs)= if tb {(1isize,k as isize)} else {(n as isize,1)};
  let mut f=|| unsafe{ if blas {
      cblas_sgemm(101, if ta{112}else{111}, if tb{112}else{111}, m as i32,n as i32,k as i32,1.0,a.as_ptr(), if ta{m as i32}else{k as i32}, b.as_ptr(), if tb{k as i32}else{n as i32},0.0,c.as_mut_ptr(),n as i32);
    } else {
      gemm::gemm(m,n,k,c.as_mut_ptr(),1,n as isize,false,a.as_ptr(),acs,ars,b.as_ptr(),bcs,brs,0.0,1.0,false,false,false,gemm::Parallelism::None);
    }};
  for _ in 0..20 { f(); }
  let mut best=f64::MAX;
  for _ in 0..7 { let t=Instant::now(); let it=50; for _ in 0..it { f(); } best=best.min(t.elapsed().as_secs_f64()/it as f64); }
  2.0*(m*n*k) as f64/best/1e9
}
fn main(){
  unsafe{openblas_set_num_threads(1);}
  let shapes=[("sac fwd NN",1024,256,256,false,false),("sac dx NT",1024,256,256,false,true),("sac dW TN",256,256,1024,true,false),
    ("sac first NN k26",1024,256,26,false,false),("sac first dW TN",26,256,1024,true,false),("sac last NN n1",1024,1,256,false,false),("sac last dx NT",1024,256,1,false,true),
    ("disc fwd NN",2048,512,512,false,false),("disc dx NT",2048,512,512,false,true),("disc dW TN",512,512,2048,true,false)];
  for (nm,m,n,k,ta,tb) in shapes { let g=run(m,n,k,ta,tb,false); let o=run(m,n,k,ta,tb,true); println!("{nm:18} m{m} n{n} k{k}: gemm {g:6.1}  openblas {o:6.1} GFLOP/s"); }
}
