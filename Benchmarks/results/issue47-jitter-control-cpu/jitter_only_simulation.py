import numpy as np, sys
def readpfm(p):
    with open(p,'rb') as f:
        h=f.readline().strip(); w,hh=map(int,f.readline().split()); s=float(f.readline())
        d=np.frombuffer(f.read(),dtype='<f4' if s<0 else '>f4')
    c=3 if h==b'PF' else 1
    return d.reshape(hh,w,c)[::-1]
hi=readpfm(sys.argv[1]).astype(np.float64)   # 1024^2 pixel centres, converged
S=4; H=hi.shape[0]//S; W=hi.shape[1]//S; C=hi.shape[2]
sub=hi.reshape(H,S,W,S,C).transpose(0,2,1,3,4)  # H,W,sy,sx,C
ref=sub.mean(axis=(2,3))
bg=ref[0,0]
vol=np.any(np.abs(ref-bg)>1e-3,axis=2)
print("volume pixels", vol.sum(), "of", H*W)
rng=np.random.default_rng(1)
def psnr(img):
    mse=((img-ref)**2)[vol].mean(); return 10*np.log10(1/mse), mse
res={"jitter":[], "cv":[], "cv_fd1":[], "centre":[]}
for trial in range(20):
    ky=rng.integers(0,S,(H,W)); kx=rng.integers(0,S,(H,W))
    yy,xx=np.meshgrid(np.arange(H),np.arange(W),indexing='ij')
    f=sub[yy,xx,ky,kx]        # H,W,C
    oy=(ky+0.5)/S-0.5; ox=(kx+0.5)/S-0.5
    # neighbours' estimates (their own jitter), central differences; borders: zero slope
    Dx=np.zeros_like(f); Dy=np.zeros_like(f)
    Dx[:,1:-1]=(f[:,2:]-f[:,:-2])/2; Dy[1:-1,:]=(f[2:,:]-f[:-2,:])/2
    cv=f-Dx*ox[...,None]-Dy*oy[...,None]
    res["jitter"].append(psnr(f)[1]); res["cv"].append(psnr(cv)[1])
    # positions of the neighbours known: slope from (f_r - f_l)/(x_r - x_l) in pixel units
    xr=1+ox[:,2:]; xl=-1+ox[:,:-2]
    Dx2=np.zeros_like(f); Dx2[:,1:-1]=(f[:,2:]-f[:,:-2])/(xr-xl)[...,None]
    yr=1+oy[2:,:]; yl=-1+oy[:-2,:]
    Dy2=np.zeros_like(f); Dy2[1:-1,:]=(f[2:,:]-f[:-2,:])/(yr-yl)[...,None]
    cv2=f-Dx2*ox[...,None]-Dy2*oy[...,None]
    res["cv_fd1"].append(psnr(cv2)[1])
centre=None
for k,v in res.items():
    if v: m=np.mean(v); print(f"{k:8s} MSE {m:.3e}  PSNR {10*np.log10(1/m):.2f} dB")
