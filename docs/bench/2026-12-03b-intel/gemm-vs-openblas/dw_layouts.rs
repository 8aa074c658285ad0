// The weight gradient dW = x^T g three ways with the gemm crate (see gemm_vs_openblas.rs for the build).
use std::time::Instant;
fn time(mut f: impl FnMut())->f64{ for _ in 0..20 { f(); } let mut best=f64::MAX;
  for _ in 0..7 { let t=Instant::now(); let it=50; for _ in 0..it { f(); } best=best.min(t.elapsed().as_secs_f64()/it as f64); } best }
// dW (din x dout) = x^T g, x: rows x din, g: rows x dout
fn main(){
 for (rows,din,dout) in [(1024usize,256usize,256usize),(2048,512,512),(1024,26,256)] {
  let x:Vec<f32>=(0..rows*din).map(|i|(i%7) as f32*0.1).collect(); let g:Vec<f32>=(0..rows*dout).map(|i|(i%5) as f32*0.1).collect();
  let mut c=vec![0f32;din*dout]; let mut xt=vec![0f32;rows*din];
  let fl=2.0*(rows*din*dout) as f64/1e9;
  let v1=time(||unsafe{gemm::gemm(din,dout,rows,c.as_mut_ptr(),1,dout as isize,false,x.as_ptr(),din as isize,1,g.as_ptr(),1,dout as isize,0.0,1.0,false,false,false,gemm::Parallelism::None)});
  // v2: compute C^T (dout x din) = g^T x, written through transposed dst strides
  let v2=time(||unsafe{gemm::gemm(dout,din,rows,c.as_mut_ptr(),dout as isize,1,false,g.as_ptr(),dout as isize,1,x.as_ptr(),1,din as isize,0.0,1.0,false,false,false,gemm::Parallelism::None)});
  // v3: transpose x then NN
  let v3=time(||{ for r in 0..rows { for i in 0..din { xt[i*rows+r]=x[r*din+i]; } }
     unsafe{gemm::gemm(din,dout,rows,c.as_mut_ptr(),1,dout as isize,false,xt.as_ptr(),1,rows as isize,g.as_ptr(),1,dout as isize,0.0,1.0,false,false,false,gemm::Parallelism::None)}});
  let t_only=time(||{ for r in 0..rows { for i in 0..din { xt[i*rows+r]=x[r*din+i]; } } });
  println!("rows{rows} din{din} dout{dout}: v1 {:.1} v2 {:.1} v3 {:.1} GFLOP/s (transpose alone {:.1} us)", fl/v1, fl/v2, fl/v3, t_only*1e6);
 }
}
