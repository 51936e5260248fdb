#!/usr/bin/env python3
"""Real poles of Bergh-Tijdeman lines in series, computed independently of the Rust crate.

An independent check (see src/physics/NOTES.md, "Lines in series: real
poles"). Needs only mpmath (`pip install --user mpmath`); not part of the build or the tests.

The response of tubes in series closed by an end volume V is p_end/p_in = 1/M11 of the ABCD
chain of README 1.2 (tube [[cosh G, Zs L sinh G/G], [Yp L sinh G/G, cosh G]], volume shunt
sV/(k p_s)); the literal BT recursion is transcribed too and both are compared. On the negative
real axis s = -sigma every quantity is real, so the real poles are the sign changes of M11(-sigma)
(a singular point of the Bessel ratios also changes sign; it is told apart by |M11| there). A
fine linear scan, bisection, and the argument principle around the slow pole (exactly one zero,
so no close pair can hide behind a single sign change).

Usage: python3 bench/bt_series_real_poles.py   (about two minutes)
"""
import mpmath as mp

mp.mp.dps = 20
RG, GAMMA, PR = mp.mpf("287.05"), mp.mpf("1.4"), mp.mpf("0.71")


def gas(T, p=101325):
    T, p = mp.mpf(T), mp.mpf(p)
    mu = mp.mpf("1.716e-5") * (T / mp.mpf("273.15")) ** 1.5 * (mp.mpf("273.15") + mp.mpf("110.4")) / (T + mp.mpf("110.4"))
    rho = p / (RG * T)
    return dict(p=p, rho=rho, nu=mu / rho, g=GAMMA, Pr=PR)


def bessel_ratio(w):
    """J2(sqrt w)/J0(sqrt w), even in sqrt w."""
    z = mp.sqrt(w)
    return mp.besselj(2, z) / mp.besselj(0, z)


def tube_parameters(G, L, R, s):
    A = mp.pi * R**2
    a2 = -s * R**2 / G["nu"]
    b = bessel_ratio(a2)
    n = 1 / (1 + (G["g"] - 1) / G["g"] * bessel_ratio(a2 * G["Pr"]))
    Zs = -s * G["rho"] / (A * b)
    Yp = s * A / (n * G["p"])
    return dict(L=L, A=A, b=b, n=n, Zs=Zs, Yp=Yp, phi=mp.sqrt(Zs * Yp), Vt=A * L)


def m11(G, tubes, V, s, k=1.4):
    """M11 of the ABCD chain: 1/H."""
    m = mp.eye(2)
    for L, R in tubes:
        t = tube_parameters(G, mp.mpf(L), mp.mpf(R), s)
        g = mp.sqrt(t["Zs"] * t["Yp"]) * t["L"]
        c, sc = mp.cosh(g), mp.sinh(g) / g
        m = m * mp.matrix([[c, t["Zs"] * t["L"] * sc], [t["Yp"] * t["L"] * sc, c]])
    m = m * mp.matrix([[1, 0], [s * mp.mpf(V) / (mp.mpf(k) * G["p"]), 1]])
    return m[0, 0]


def bt_recursion(G, tubes, V, s, k=1.4):
    """Literal BT (1965) recursion, volume V at the end of the last tube: p_N/p_0."""
    P = [tube_parameters(G, mp.mpf(L), mp.mpf(R), s) for L, R in tubes]
    total, nxt = mp.mpf(1), None
    for j in reversed(range(len(P))):
        x = P[j]["phi"] * P[j]["L"]
        vv = mp.mpf(V) if j == len(P) - 1 else 0
        d = mp.cosh(x) + vv / P[j]["Vt"] / mp.mpf(k) * P[j]["n"] * x * mp.sinh(x)
        if j < len(P) - 1:
            q = P[j + 1]
            y = q["phi"] * q["L"]
            d += (q["Vt"] / P[j]["Vt"]) * (q["phi"] / P[j]["phi"]) * (P[j]["L"] / q["L"]) \
                * (q["b"] / P[j]["b"]) * mp.sinh(x) / mp.sinh(y) * (mp.cosh(y) - nxt)
        nxt = 1 / d
        total *= nxt
    return total


def real_poles(G, tubes, V, smax, step):
    f = lambda sig: float(mp.re(m11(G, tubes, V, mp.mpc(-sig, 0))))
    out, xp = [], step / 2
    fp = f(xp)
    x = xp
    while x < smax:
        x += step
        fx = f(x)
        if (fx > 0) != (fp > 0):
            lo, hi, flo = x - step, x, fp
            for _ in range(55):
                mid = (lo + hi) / 2
                fm = f(mid)
                if (fm > 0) == (flo > 0):
                    lo, flo = mid, fm
                else:
                    hi = mid
            r = (lo + hi) / 2
            if abs(f(r)) < 1e-6 * max(abs(fx), abs(fp), 1.0):  # a zero, not a singular point
                h = 1e-7 * r
                slope = (f(r + h) - f(r - h)) / (2 * h)
                out.append((r, 1 / abs(slope * r)))  # weight |Res/sigma| in the step response
        fp = fx
    return out


def zeros_in_box(G, tubes, V, x0, x1, y0, y1, n=300):
    """Zeros minus poles of M11 in the box (argument principle)."""
    corners = [mp.mpc(x0, y0), mp.mpc(x1, y0), mp.mpc(x1, y1), mp.mpc(x0, y1), mp.mpc(x0, y0)]
    tot, prev = 0, m11(G, tubes, V, corners[0])
    for a, b in zip(corners, corners[1:]):
        for i in range(1, n + 1):
            v = m11(G, tubes, V, a + (b - a) * i / n)
            tot += mp.arg(v / prev)
            prev = v
    return float(tot / (2 * mp.pi))


if __name__ == "__main__":
    three = [(0.1, 0.25e-3), (1.0, 1.5e-3), (0.3, 0.5e-3)]
    two = [(0.1, 0.25e-3), (1.0, 1.5e-3)]
    G = gas(288.15)
    s = mp.mpc(0, 2 * mp.pi * 5)
    print("three-line |H(5 Hz)| chain %.5f, chain/recursion - 1 = %.1e" % (
        abs(1 / m11(G, three, 3e-7, s)), abs(bt_recursion(G, three, 3e-7, s) * m11(G, three, 3e-7, s) - 1)))
    cases = [("three-line", three, 3e-7, 288.15)] + [
        ("two-line", two, V, T) for T in (288.15, 293.15) for V in (3e-7, 0.0)]
    for name, tubes, V, T in cases:
        G = gas(T)
        poles = [(r, w) for r, w in real_poles(G, tubes, V, 120.0, 0.01) if w > 1e-3]
        box = zeros_in_box(G, tubes, V, -13.0, -9.5, -2.0, 2.0)
        print("%-10s V %-6g T %.2f K: real poles %s; zeros of M11 in [-13,-9.5]x[-2,2]i: %.3f" % (
            name, V, T, ", ".join("-%.4f (weight %.3f)" % (r, w) for r, w in poles), box))
