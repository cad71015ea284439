#!/usr/bin/env python3
"""A skinned figure that walks: 11 boxes, each bound to one bone of a hips/spine/head/arms/legs
skeleton, a 2 s walk cycle (hips turn and bob, legs and arms swing, knees and elbows bend,
head turns), written as glTF 2.0 with an embedded buffer. A moving body where nearly every
occupied cell changes over time, for the 4D bake's measurements (BENCH.md §6, 4D).

Usage: python3 scripts/walker_gltf.py OUT.gltf
"""
import base64, json, math, struct, sys
parts = [  # name, bone, centre (bind pose), size, colour
 ("hips","hips",(0,1.0,0),(0.36,0.16,0.2),(0.2,0.3,0.7)),
 ("torso","spine",(0,1.3,0),(0.4,0.45,0.22),(0.8,0.25,0.2)),
 ("head","head",(0,1.68,0),(0.22,0.24,0.22),(0.95,0.8,0.6)),
 ("luarm","lsh",(0.28,1.38,0),(0.11,0.3,0.11),(0.8,0.25,0.2)),
 ("llarm","lel",(0.28,1.09,0),(0.09,0.28,0.09),(0.95,0.8,0.6)),
 ("ruarm","rsh",(-0.28,1.38,0),(0.11,0.3,0.11),(0.8,0.25,0.2)),
 ("rlarm","rel",(-0.28,1.09,0),(0.09,0.28,0.09),(0.95,0.8,0.6)),
 ("luleg","lhip",(0.1,0.72,0),(0.14,0.4,0.14),(0.2,0.3,0.7)),
 ("llleg","lkn",(0.1,0.3,0),(0.12,0.42,0.12),(0.3,0.3,0.35)),
 ("ruleg","rhip",(-0.1,0.72,0),(0.14,0.4,0.14),(0.2,0.3,0.7)),
 ("rlleg","rkn",(-0.1,0.3,0),(0.12,0.42,0.12),(0.3,0.3,0.35)),
]
# bone: parent, joint position (bind, world)
bones = {"hips":(None,(0,1.0,0)),"spine":("hips",(0,1.08,0)),"head":("spine",(0,1.55,0)),
 "lsh":("spine",(0.28,1.52,0)),"lel":("lsh",(0.28,1.23,0)),"rsh":("spine",(-0.28,1.52,0)),"rel":("rsh",(-0.28,1.23,0)),
 "lhip":("hips",(0.1,0.92,0)),"lkn":("lhip",(0.1,0.52,0)),"rhip":("hips",(-0.1,0.92,0)),"rkn":("rhip",(-0.1,0.52,0))}
names = list(bones)
bi = {n:i for i,n in enumerate(names)}
def q(axis, ang):
    s=math.sin(ang/2); return [axis[0]*s,axis[1]*s,axis[2]*s,math.cos(ang/2)]
def qmul(a,b):
    x1,y1,z1,w1=a; x2,y2,z2,w2=b
    return [w1*x2+x1*w2+y1*z2-z1*y2, w1*y2-x1*z2+y1*w2+z1*x2, w1*z2+x1*y2-y1*x2+z1*w2, w1*w2-x1*x2-y1*y2-z1*z2]
nodes=[{"name":"body","mesh":0,"skin":0}]
for n in names:
    p,pos=bones[n]; pp=bones[p][1] if p else (0,0,0)
    nodes.append({"name":n,"translation":[pos[k]-pp[k] for k in range(3)]})
for n in names:
    p=bones[n][0]
    if p: nodes[1+bi[p]].setdefault("children",[]).append(1+bi[n])
buf=bytearray(); views=[]; accs=[]
def add(data, fmt, count, typ, ctype, target=None, mm=False):
    off=len(buf); b=b"".join(struct.pack("<"+fmt, *d) if isinstance(d,(list,tuple)) else struct.pack("<"+fmt,d) for d in data)
    buf.extend(b)
    while len(buf)%4: buf.append(0)
    v={"buffer":0,"byteOffset":off,"byteLength":len(b)}
    if target: v["target"]=target
    views.append(v); a={"bufferView":len(views)-1,"componentType":ctype,"count":count,"type":typ}
    if mm:
        cols=list(zip(*data)); a["min"]=[min(c) for c in cols]; a["max"]=[max(c) for c in cols]
    accs.append(a); return len(accs)-1
prims=[]; mats=[]
faces=[((1,0,0),(0,1,0),(0,0,1)),((-1,0,0),(0,1,0),(0,0,-1)),((0,1,0),(0,0,1),(1,0,0)),((0,-1,0),(0,0,1),(-1,0,0)),((0,0,1),(1,0,0),(0,1,0)),((0,0,-1),(1,0,0),(0,-1,0))]
for name,bone,c,sz,col in parts:
    P=[];N=[];C=[];I=[];J=[];W=[]
    for (n,u,v) in faces:
        base=len(P)
        for su,sv in [(-1,-1),(1,-1),(1,1),(-1,1)]:
            p=[c[k]+0.5*sz[k]*(n[k]+su*u[k]+sv*v[k]) for k in range(3)]
            P.append(p); N.append(list(n))
            # a two-tone gradient so sliding surfaces change colour
            f=0.75+0.25*su*sv
            C.append([col[0]*f,col[1]*f,col[2]*(2-f)*0.5+0.0,1.0])
            J.append([bi[bone],0,0,0]); W.append([1.0,0,0,0])
        # winding: u x v = n
        I+= [base,base+1,base+2,base,base+2,base+3]
    pa=add(P,"3f",len(P),"VEC3",5126,34962,True); na=add(N,"3f",len(N),"VEC3",5126,34962)
    ca=add(C,"4f",len(C),"VEC4",5126,34962); ja=add(J,"4H",len(J),"VEC4",5123,34962); wa=add(W,"4f",len(W),"VEC4",5126,34962)
    ia=add(I,"H",len(I),"SCALAR",5123,34963)
    mats.append({"pbrMetallicRoughness":{"baseColorFactor":[1,1,1,1],"metallicFactor":0.0,"roughnessFactor":0.8}})
    prims.append({"attributes":{"POSITION":pa,"NORMAL":na,"COLOR_0":ca,"JOINTS_0":ja,"WEIGHTS_0":wa},"indices":ia,"material":len(mats)-1})
ibm=[]
for n in names:
    p=bones[n][1]; ibm.append([1,0,0,0, 0,1,0,0, 0,0,1,0, -p[0],-p[1],-p[2],1])
ibma=add(ibm,"16f",len(ibm),"MAT4",5126)
# walk cycle over 2 s, 17 keys
T=[2.0*i/16 for i in range(17)]
ta=add(T,"f",len(T),"SCALAR",5126,None,False); accs[ta]["min"]=[0.0]; accs[ta]["max"]=[2.0]
chans=[];samps=[]
def rot(bone, fn):
    out=[fn(2*math.pi*t/2.0) for t in T]
    oa=add(out,"4f",len(out),"VEC4",5126)
    samps.append({"input":ta,"output":oa,"interpolation":"LINEAR"}); chans.append({"sampler":len(samps)-1,"target":{"node":1+bi[bone],"path":"rotation"}})
X=(1,0,0); Y=(0,1,0)
rot("hips", lambda ph: q(Y, 0.5*math.sin(ph)))
rot("lhip", lambda ph: q(X, 0.6*math.sin(ph)))
rot("rhip", lambda ph: q(X, -0.6*math.sin(ph)))
rot("lkn", lambda ph: q(X, 0.5+0.5*math.sin(ph+1.5)))
rot("rkn", lambda ph: q(X, 0.5+0.5*math.sin(ph+1.5+math.pi)))
rot("lsh", lambda ph: q(X, -0.7*math.sin(ph)))
rot("rsh", lambda ph: q(X, 0.7*math.sin(ph)))
rot("lel", lambda ph: q(X, -0.6-0.3*math.sin(ph)))
rot("rel", lambda ph: q(X, -0.6+0.3*math.sin(ph)))
rot("head", lambda ph: q(Y, 0.4*math.sin(2*ph)))
# hips bob (translation)
tr=[[0,1.0+0.04*math.cos(2*2*math.pi*t/2.0),0] for t in T]
oa=add(tr,"3f",len(tr),"VEC3",5126); samps.append({"input":ta,"output":oa,"interpolation":"LINEAR"}); chans.append({"sampler":len(samps)-1,"target":{"node":1+bi["hips"],"path":"translation"}})
g={"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0,1]}],"nodes":nodes,"meshes":[{"primitives":prims}],
 "skins":[{"inverseBindMatrices":ibma,"joints":[1+bi[n] for n in names]}],"materials":mats,
 "animations":[{"channels":chans,"samplers":samps}],
 "buffers":[{"byteLength":len(buf),"uri":"data:application/octet-stream;base64,"+base64.b64encode(bytes(buf)).decode()}],
 "bufferViews":views,"accessors":accs}
with open(sys.argv[1] if len(sys.argv) > 1 else "walker.gltf", "w") as f:
    json.dump(g, f)
