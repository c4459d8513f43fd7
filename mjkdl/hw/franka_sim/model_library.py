"""The arm's model as the binary library a libfranka 0.9 client downloads (protocol 5).

libfranka before 0.18 computes kinematics and dynamics in Franka's closed model library
(`libfcimodels`): the robot sends a shared library through the `LoadModelLibrary` service
command and the client loads it and calls its 31 C functions (`src/libfcimodels.h`: the poses
`O_T_J1..9`, the zero and body Jacobians `O_J_J1..9` and `Ji_J_J1..9` of the seven joint frames,
the flange and the end effector, the mass matrix `M_NE`, the Coriolis vector `c_NE` and the
gravity vector `g_NE`). The simulator writes that library itself: C source holding the same
rigid-body model libfranka >= 0.18 builds from the URDF the server sends (links 1 to 7 and the
flange, no rotor inertia), compiled with the system's C compiler and kept under
`model_library_cache_dir()`, keyed by the source's hash.

Conventions (libfranka's `model.cpp`): matrices column-major; Jacobians 6×7 with the linear
rows first, zero Jacobians in the base frame, body Jacobians in the frame itself, columns of the
joints beyond the frame zero; the load (`m`, `F_x_C` in the flange frame, `I` about its centre of
mass in flange axes: libfranka passes the hand and the user's load combined) rides on the
flange; `g_NE` is the torque that holds the arm against `g_earth` (the base's acceleration,
`O_ddP_O` = (0, 0, -9.81)).
"""

from __future__ import annotations

import hashlib
import os
import platform
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pinocchio as pin

from mjkdl.errors import MjkdlError

# LoadModelLibrary's request: the client's architecture and operating system (libfranka-common
# `research_interface/robot/service_types.h`, protocol 5).
ARCHITECTURES = {0: "x86_64", 1: "x86", 2: "arm", 3: "arm64"}
SYSTEMS = {0: "linux", 1: "windows"}
_MACHINES = {"x86_64": "x86_64", "amd64": "x86_64", "aarch64": "arm64", "arm64": "arm64"}
_FLAGS = ("-O2", "-shared", "-fPIC")


class ModelLibraryError(MjkdlError, RuntimeError):
    """The model library for a libfranka 0.9 client cannot be made here."""


def model_library_cache_dir() -> Path:
    """Where compiled model libraries are kept: `$MJKDL_CACHE_DIR/franka_models`, else
    `$XDG_CACHE_HOME/mjkdl/franka_models`, else `~/.cache/mjkdl/franka_models`. Safe to
    delete."""
    base = os.environ.get("MJKDL_CACHE_DIR")
    if base:
        return Path(base).expanduser() / "franka_models"
    cache = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(cache).expanduser() / "mjkdl" / "franka_models"


def _array(name: str, values: np.ndarray) -> str:
    """A C array of doubles (1-D or 2-D) printed to round-trip exactly."""
    values = np.asarray(values, dtype=float)

    def row(v: np.ndarray) -> str:
        return "{" + ", ".join(f"{x:.17g}" for x in v) + "}"

    body = row(values) if values.ndim == 1 else "{" + ", ".join(row(v) for v in values) + "}"
    shape = "".join(f"[{n}]" for n in values.shape)
    return f"static const double {name}{shape} = {body};"


def model_library_source(urdf: str) -> str:
    """C source of the 31 functions for the arm described by `urdf` (the server's own URDF,
    read through Pinocchio: joint placements, link inertias and the flange `link8`)."""
    model = pin.buildModelFromXML(urdf)
    if model.nq != 7 or not model.existFrame("link8"):
        raise ModelLibraryError(
            f"the arm's URDF has {model.nq} joints and link8 {model.existFrame('link8')}: the "
            "model library describes a 7-joint Franka arm ending in the flange link8"
        )
    flange = model.frames[model.getFrameId("link8")]
    if flange.parentJoint != 7:
        raise ModelLibraryError("the arm's URDF hangs the flange link8 off another joint than 7")
    placements = [model.jointPlacements[i] for i in range(1, 8)]
    inertias = [model.inertias[i] for i in range(1, 8)]
    constants = [
        _array("PL_R", np.array([p.rotation.ravel() for p in placements])),
        _array("PL_P", np.array([p.translation for p in placements])),
        _array("MASS", np.array([i.mass for i in inertias])),
        _array("COM", np.array([i.lever for i in inertias])),
        _array("INERTIA", np.array([i.inertia.ravel() for i in inertias])),
        _array("FL_R", flange.placement.rotation.ravel()),
        _array("FL_P", flange.placement.translation),
    ]
    return _HEADER + "\n".join(constants) + "\n" + _BODY + _exports()


def _exports() -> str:
    lines = [
        "EXPORT void Ji_J_J1(double out[42]) { jacobian(ZERO7, 1, 0, 1, out); }",
        "EXPORT void O_J_J1(double out[42]) { jacobian(ZERO7, 1, 0, 0, out); }",
    ]
    for k in range(1, 9):
        if k > 1:
            lines += [
                f"EXPORT void Ji_J_J{k}(const double q[7], double out[42]) "
                f"{{ jacobian(q, {k}, 0, 1, out); }}",
                f"EXPORT void O_J_J{k}(const double q[7], double out[42]) "
                f"{{ jacobian(q, {k}, 0, 0, out); }}",
            ]
        lines.append(
            f"EXPORT void O_T_J{k}(const double q[7], double out[16]) "
            f"{{ pose_of(q, {k}, 0, out); }}"
        )
    ee = "const double q[7], const double F_T_EE[16], double out"
    lines += [
        f"EXPORT void Ji_J_J9({ee}[42]) {{ jacobian(q, 9, F_T_EE, 1, out); }}",
        f"EXPORT void O_J_J9({ee}[42]) {{ jacobian(q, 9, F_T_EE, 0, out); }}",
        f"EXPORT void O_T_J9({ee}[16]) {{ pose_of(q, 9, F_T_EE, out); }}",
    ]
    return "\n".join(lines) + "\n"


_HEADER = """\
/* The Franka arm's model library (libfcimodels), written by mjkdl from the simulated arm. */
#include <math.h>
#include <string.h>
#define EXPORT __attribute__((visibility("default")))
"""

# Rigid-body algorithms on 3-vectors and row-major 3x3 rotations. Link i's frame is its joint's:
# placed at PL_R/PL_P in the parent, turned by q_i about its z axis.
_BODY = """\
static const double ZERO7[7] = {0, 0, 0, 0, 0, 0, 0};
typedef struct { double R[9]; double p[3]; } Tf;

static void mv(const double R[9], const double v[3], double out[3]) {
  for (int r = 0; r < 3; ++r) out[r] = R[3 * r] * v[0] + R[3 * r + 1] * v[1] + R[3 * r + 2] * v[2];
}
static void mtv(const double R[9], const double v[3], double out[3]) {
  for (int c = 0; c < 3; ++c) out[c] = R[c] * v[0] + R[3 + c] * v[1] + R[6 + c] * v[2];
}
static void cross(const double a[3], const double b[3], double out[3]) {
  double o0 = a[1] * b[2] - a[2] * b[1], o1 = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
  out[0] = o0;
  out[1] = o1;
}
static void compose(const Tf *a, const Tf *b, Tf *out) {
  Tf t;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      t.R[3 * r + c] = a->R[3 * r] * b->R[c] + a->R[3 * r + 1] * b->R[3 + c] +
                       a->R[3 * r + 2] * b->R[6 + c];
  mv(a->R, b->p, t.p);
  for (int r = 0; r < 3; ++r) t.p[r] += a->p[r];
  *out = t;
}
/* link i (0-based) in its parent at joint angle q */
static void local(int i, double q, Tf *out) {
  double c = cos(q), s = sin(q);
  const double *P = PL_R[i];
  for (int r = 0; r < 3; ++r) {
    out->R[3 * r] = P[3 * r] * c + P[3 * r + 1] * s;
    out->R[3 * r + 1] = -P[3 * r] * s + P[3 * r + 1] * c;
    out->R[3 * r + 2] = P[3 * r + 2];
    out->p[r] = PL_P[i][r];
  }
}
static void from_col(const double m[16], Tf *out) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out->R[3 * r + c] = m[4 * c + r];
    out->p[r] = m[12 + r];
  }
}
static void to_col(const Tf *t, double m[16]) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m[4 * c + r] = t->R[3 * r + c];
    m[12 + r] = t->p[r];
    m[4 * r + 3] = 0.0;
  }
  m[15] = 1.0;
}
/* frames[j]: link j+1 in the base for the joints the frame k (1..7 links, 8 flange, 9 EE)
   depends on; the frame k itself in *frame */
static void chain(const double q[7], int k, const double F_T_EE[16], Tf frames[7], Tf *frame) {
  int n = k < 7 ? k : 7;
  Tf t;
  for (int j = 0; j < n; ++j) {
    local(j, q[j], &t);
    if (j == 0) frames[0] = t; else compose(&frames[j - 1], &t, &frames[j]);
  }
  *frame = frames[n - 1];
  if (k >= 8) {
    Tf fl;
    memcpy(fl.R, FL_R, sizeof fl.R);
    memcpy(fl.p, FL_P, sizeof fl.p);
    compose(frame, &fl, frame);
  }
  if (k == 9) {
    Tf ee;
    from_col(F_T_EE, &ee);
    compose(frame, &ee, frame);
  }
}
static void pose_of(const double q[7], int k, const double F_T_EE[16], double out[16]) {
  Tf frames[7], frame;
  chain(q, k, F_T_EE, frames, &frame);
  to_col(&frame, out);
}
/* column j: the z axis of link j+1 and its velocity at the frame's origin, in the base
   (body: in the frame) */
static void jacobian(const double q[7], int k, const double F_T_EE[16], int body, double out[42]) {
  Tf frames[7], frame;
  chain(q, k, F_T_EE, frames, &frame);
  memset(out, 0, 42 * sizeof(double));
  int n = k < 7 ? k : 7;
  for (int j = 0; j < n; ++j) {
    double z[3] = {frames[j].R[2], frames[j].R[5], frames[j].R[8]}, d[3], v[3];
    for (int r = 0; r < 3; ++r) d[r] = frame.p[r] - frames[j].p[r];
    cross(z, d, v);
    if (body) {
      mtv(frame.R, v, out + 6 * j);
      mtv(frame.R, z, out + 6 * j + 3);
    } else {
      memcpy(out + 6 * j, v, sizeof v);
      memcpy(out + 6 * j + 3, z, sizeof z);
    }
  }
}
/* link 7 with the flange load (m, c in the flange, I about c in flange axes, column-major) */
static void link7_with(const double I_load[9], double m_load, const double c_load[3], double *m,
                       double c[3], double I[9]) {
  double cl[3], rl[9], il[9];
  mv(FL_R, c_load, cl);
  for (int r = 0; r < 3; ++r) cl[r] += FL_P[r];
  /* R I R^T, I read column-major */
  for (int r = 0; r < 3; ++r)
    for (int s = 0; s < 3; ++s) {
      double acc = 0.0;
      for (int a = 0; a < 3; ++a) acc += FL_R[3 * r + a] * I_load[3 * s + a];
      rl[3 * r + s] = acc; /* (R I)[r][s], I symmetric */
    }
  for (int r = 0; r < 3; ++r)
    for (int s = 0; s < 3; ++s)
      il[3 * r + s] = rl[3 * r] * FL_R[3 * s] + rl[3 * r + 1] * FL_R[3 * s + 1] +
                      rl[3 * r + 2] * FL_R[3 * s + 2];
  double m7 = MASS[6];
  *m = m7 + m_load;
  for (int r = 0; r < 3; ++r) c[r] = (m7 * COM[6][r] + m_load * cl[r]) / *m;
  /* parallel axes: each part's inertia moved to the joint centre of mass */
  for (int r = 0; r < 9; ++r) I[r] = INERTIA[6][r] + (m_load != 0.0 ? il[r] : 0.0);
  const double *parts[2] = {COM[6], cl};
  double masses[2] = {m7, m_load};
  for (int p = 0; p < 2; ++p) {
    double d[3] = {parts[p][0] - c[0], parts[p][1] - c[1], parts[p][2] - c[2]};
    double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    for (int r = 0; r < 3; ++r)
      for (int s = 0; s < 3; ++s) I[3 * r + s] += masses[p] * ((r == s ? dd : 0.0) - d[r] * d[s]);
  }
}
/* Recursive Newton-Euler: tau = M(q) ddq + C(q, dq) dq + the torque against a base
   accelerating at a0 (the negative of gravity), the load on the flange. */
static void rnea(const double q[7], const double dq[7], const double ddq[7], const double a0[3],
                 const double I_load[9], double m_load, const double c_load[3], double tau[7]) {
  Tf X[7];
  double w[7][3], dw[7][3], a[7][3], F[7][3], N[7][3];
  double m7, c7[3], I7[9];
  link7_with(I_load, m_load, c_load, &m7, c7, I7);
  double wp[3] = {0, 0, 0}, dwp[3] = {0, 0, 0}, ap[3] = {a0[0], a0[1], a0[2]};
  for (int i = 0; i < 7; ++i) {
    local(i, q[i], &X[i]);
    double t[3], u[3], s[3];
    const double *p = X[i].p;
    /* a_i = R^T (a_p + dw_p x p + w_p x (w_p x p)) */
    cross(dwp, p, t);
    cross(wp, p, u);
    cross(wp, u, s);
    for (int r = 0; r < 3; ++r) u[r] = ap[r] + t[r] + s[r];
    mtv(X[i].R, u, a[i]);
    double wl[3], dwl[3];
    mtv(X[i].R, wp, wl);
    mtv(X[i].R, dwp, dwl);
    /* w = wl + z dq; dw = dwl + wl x z dq + z ddq */
    w[i][0] = wl[0]; w[i][1] = wl[1]; w[i][2] = wl[2] + dq[i];
    dw[i][0] = dwl[0] + wl[1] * dq[i];
    dw[i][1] = dwl[1] - wl[0] * dq[i];
    dw[i][2] = dwl[2] + ddq[i];
    double m = i == 6 ? m7 : MASS[i];
    const double *c = i == 6 ? c7 : COM[i];
    const double *I = i == 6 ? I7 : INERTIA[i];
    double ac[3];
    cross(dw[i], c, t);
    cross(w[i], c, u);
    cross(w[i], u, s);
    for (int r = 0; r < 3; ++r) {
      ac[r] = a[i][r] + t[r] + s[r];
      F[i][r] = m * ac[r];
    }
    double Iw[3], Idw[3];
    mv(I, w[i], Iw);
    mv(I, dw[i], Idw);
    cross(w[i], Iw, t);
    for (int r = 0; r < 3; ++r) N[i][r] = Idw[r] + t[r];
    memcpy(wp, w[i], sizeof wp);
    memcpy(dwp, dw[i], sizeof dwp);
    memcpy(ap, a[i], sizeof ap);
  }
  double f[3] = {0, 0, 0}, n[3] = {0, 0, 0};
  for (int i = 6; i >= 0; --i) {
    double fc[3], nc[3], t[3], u[3];
    /* the child's force and moment in this link's frame */
    if (i < 6) {
      mv(X[i + 1].R, f, fc);
      mv(X[i + 1].R, n, nc);
      cross(X[i + 1].p, fc, t);
    } else {
      memset(fc, 0, sizeof fc);
      memset(nc, 0, sizeof nc);
      memset(t, 0, sizeof t);
    }
    const double *c = i == 6 ? c7 : COM[i];
    cross(c, F[i], u);
    for (int r = 0; r < 3; ++r) {
      f[r] = F[i][r] + fc[r];
      n[r] = N[i][r] + nc[r] + u[r] + t[r];
    }
    tau[i] = n[2];
  }
}
static const double NO_INERTIA[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
static const double NO_ACCEL[3] = {0, 0, 0};
/* The composite-rigid-body algorithm: the mass of links i..7 (m, first moment h and inertia I
   about link i's origin, link i's axes) moving with joint i; M_ij is the torque about joint
   i's axis it takes to turn joint j at unit acceleration. */
EXPORT void M_NE(const double q[7], const double I_load[9], double m_load,
                 const double F_x_Cload[3], double out[49]) {
  Tf X[7];
  double mc[7], hc[7][3], Ic[7][9];
  double m7, c7[3], I7[9];
  link7_with(I_load, m_load, F_x_Cload, &m7, c7, I7);
  for (int i = 0; i < 7; ++i) {
    local(i, q[i], &X[i]);
    double m = i == 6 ? m7 : MASS[i];
    const double *c = i == 6 ? c7 : COM[i];
    const double *I = i == 6 ? I7 : INERTIA[i];
    double cc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    mc[i] = m;
    for (int r = 0; r < 3; ++r) {
      hc[i][r] = m * c[r];
      for (int k = 0; k < 3; ++k)
        Ic[i][3 * r + k] = I[3 * r + k] + m * ((r == k ? cc : 0.0) - c[r] * c[k]);
    }
  }
  for (int i = 6; i > 0; --i) {
    /* links i..7 seen from the parent's origin: I_O = R I R^T - m p^ p^ - p^ h^ - h^ p^, with
       h = R h_i the first moment in the parent's axes (p^: the cross-product matrix of p) */
    const double *R = X[i].R, *p = X[i].p;
    double h[3], RI[9], m = mc[i];
    mv(R, hc[i], h);
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k)
        RI[3 * r + k] =
            R[3 * r] * Ic[i][k] + R[3 * r + 1] * Ic[i][3 + k] + R[3 * r + 2] * Ic[i][6 + k];
    double pp = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
    double ph = p[0] * h[0] + p[1] * h[1] + p[2] * h[2];
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) {
        double rot =
            RI[3 * r] * R[3 * k] + RI[3 * r + 1] * R[3 * k + 1] + RI[3 * r + 2] * R[3 * k + 2];
        double e = r == k ? 1.0 : 0.0;
        /* -m p^p^ = m (|p|^2 E - p p^T); -(p^h^ + h^p^) = 2 (p.h) E - p h^T - h p^T */
        Ic[i - 1][3 * r + k] +=
            rot + m * (e * pp - p[r] * p[k]) + 2.0 * e * ph - p[r] * h[k] - h[r] * p[k];
      }
    mc[i - 1] += m;
    for (int r = 0; r < 3; ++r) hc[i - 1][r] += m * p[r] + h[r];
  }
  const double z[3] = {0.0, 0.0, 1.0};
  for (int j = 0; j < 7; ++j) {
    /* joint j turning at unit rate: the momentum rate of links j..7, n = I z, f = z x h */
    double n[3], f[3];
    mv(Ic[j], z, n);
    cross(z, hc[j], f);
    out[7 * j + j] = n[2];
    for (int i = j; i > 0; --i) {
      /* into link i-1's frame */
      double fp[3], np_[3], t[3];
      mv(X[i].R, f, fp);
      mv(X[i].R, n, np_);
      cross(X[i].p, fp, t);
      for (int r = 0; r < 3; ++r) {
        f[r] = fp[r];
        n[r] = np_[r] + t[r];
      }
      out[7 * j + i - 1] = out[7 * (i - 1) + j] = n[2];
    }
  }
}
EXPORT void c_NE(const double q[7], const double dq[7], const double I_load[9], double m_load,
                 const double F_x_Cload[3], double out[7]) {
  rnea(q, dq, ZERO7, NO_ACCEL, I_load, m_load, F_x_Cload, out);
}
EXPORT void g_NE(const double q[7], const double g_earth[3], double m_load,
                 const double F_x_Cload[3], double out[7]) {
  double a0[3] = {-g_earth[0], -g_earth[1], -g_earth[2]};
  rnea(q, ZERO7, ZERO7, a0, NO_INERTIA, m_load, F_x_Cload, out);
}
"""


def host_architecture() -> str:
    """This machine's architecture in LoadModelLibrary's names ('x86_64', 'arm64', ...)."""
    return _MACHINES.get(platform.machine().lower(), platform.machine().lower())


def compile_model_library(urdf: str, cache: Path | None = None) -> Path:
    """The compiled library for `urdf` (built once per source, then taken from `cache`)."""
    source = model_library_source(urdf)
    wanted = os.environ.get("CC")
    compiler = shutil.which(wanted) if wanted else shutil.which("cc") or shutil.which("gcc")
    key = hashlib.sha256((source + " ".join(_FLAGS)).encode()).hexdigest()[:16]
    cache = cache or model_library_cache_dir()
    target = cache / f"libfcimodels-{key}.so"
    if target.is_file():
        return target
    if compiler is None:
        raise ModelLibraryError(
            "a libfranka 0.9 client (panda-py) asked for the arm's model library, which the "
            "simulator compiles from C source, and no C compiler was found (looked for "
            f"{f'CC={wanted!r}' if wanted else 'cc, gcc'}): install one (Debian/Ubuntu: "
            "apt-get install gcc) or set CC to one"
        )
    cache.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=cache) as work:
        src = Path(work) / "libfcimodels.c"
        src.write_text(source)
        built = Path(work) / target.name
        done = subprocess.run(
            [compiler, *_FLAGS, "-o", str(built), str(src), "-lm"],
            capture_output=True,
            text=True,
        )
        if done.returncode != 0:
            raise ModelLibraryError(
                f"the C compiler {compiler} failed on the arm's model library "
                f"(exit {done.returncode}): {done.stderr.strip()[:2000]}; check that it "
                "builds shared libraries (-shared -fPIC) or set CC to one that does"
            )
        os.replace(built, target)  # atomic: a concurrent server sees all of it or nothing
    return target


def model_library(urdf: str, architecture: int, system: int) -> bytes:
    """The library a client of `architecture` and `system` (LoadModelLibrary's codes) loads."""
    arch = ARCHITECTURES.get(architecture, f"code {architecture}")
    osname = SYSTEMS.get(system, f"code {system}")
    if osname != platform.system().lower() or arch != host_architecture():
        raise ModelLibraryError(
            f"the client asked for a model library for {osname} on {arch}; the simulator "
            f"compiles for its own machine ({platform.system().lower()} on "
            f"{host_architecture()}): run the client on the simulator's kind of machine"
        )
    return compile_model_library(urdf).read_bytes()
