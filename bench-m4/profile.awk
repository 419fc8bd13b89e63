# Cortex-M4 cycle estimate of the profiled windows of a bench-m4 profile run.
#
# Usage: awk -f profile.awk <llvm-objdump -d -C -l of the ELF> <PCs> <program stdout>
#
# The PCs come from QEMU's `-singlestep -d exec,nochain` trace, one line per executed
# instruction (`Trace 0: 0x... [00800400/00007940/...]`), reduced to the second field of
# the bracket (8 hex digits) by `grep '^Trace' | cut -d/ -f2`. The program prints
# `PROFILE <name> calls=<K>` for each window, in the order it runs them. A window starts
# at the entry of `harness::profile_begin` and ends at the entry of
# `harness::profile_end`; the function they return into (the harness loop) is not
# attributed to the figure. Every other instruction in the window is weighted with the
# Cortex-M4 cycle table below (ARM Cortex-M4 TRM, table 3-1, zero wait states):
#
#   ALU, move, compare, shift, bit-field, saturate, CLZ, IT ...  1
#   MUL, MLA, MLS, SMULL, UMULL, SMLAL, UMLAL, UMAAL, DSP MACs   1
#   SDIV, UDIV                                                  12 (2-12: worst case)
#   LDR/STR single (any width)                                  2, or 1 when it follows
#                                                                 another single load/store
#                                                                 (address/data pipelining)
#   LDRD, STRD                                                  3 (1 + N, N = 2)
#   LDM, STM, PUSH, POP                                         1 + N (+ P if PC is loaded)
#   B<cond>, CBZ, CBNZ                                          1 not taken, 1 + P taken
#   B, BL, BLX, BX                                              1 + P
#   TBB, TBH                                                    2 + P
#   VADD, VSUB, VMUL, VNEG, VABS, VCMP, VCVT, VMOV, VMRS        1
#   VLDR, VSTR                                                  2;  VPUSH, VPOP, VLDM, VSTM 1 + N
#   VMLA, VMLS, VFMA, VFMS (and negated forms)                  3
#   VDIV, VSQRT                                                 14
#
# P, the pipeline refill, is 1 to 3 cycles; the model takes 2. A branch is taken when the
# next traced PC is not the next instruction in the listing. Flash wait states (5 at
# 168 MHz on the STM32F407, mostly hidden by its ART accelerator) are not modelled.
#
# Source attribution: with `llvm-objdump -l`, each instruction is attributed to the last
# line of hydra_core or bench-m4 source above it in the listing (lines of the standard
# library or of the `fixed` crate are inlined helpers of that line).
#
# Output, per window (per call = divided by K):
#   PROF <name> calls=K instr_x1000=<per call> cycles_x1000=<per call>
#   CLASS <name> <class> instr_x1000=<per call> cycles_x1000=<per call>
#   FUNC <name> instr_x1000=<per call> <function>
#   MNEM <name> instr_x1000=<per call> <mnemonic>
#   SRC <name> instr_x1000=<per call> cycles_x1000=<per call> <file:line>
# and with `-v annotate=<name>`, that window's executed instructions in address order:
#   HOT <name> <address> instr_x1000=<per call> <file:line> <function> | <instruction>
BEGIN {
    P = 2
    filen = 0
}

FNR == 1 {
    filen++
    if (filen == 2) begin_pc = entry[begin_fn]
}

# An address as the trace prints it: 8 lower-case hex digits.
function pad8(a) {
    return substr("00000000", 1, 8 - length(a)) a
}

# ---- file 1: the disassembly ------------------------------------------------------------
filen == 1 && /^[0-9a-f]+ <.*>:$/ {
    fname = $0
    sub(/^[0-9a-f]+ </, "", fname)
    sub(/>:$/, "", fname)
    sub(/::h[0-9a-f]+$/, "", fname)
    cursrc = "(" fname ")"
    next
}
filen == 1 && /^; \// {
    # `; /path/to/file.rs:LINE` from `llvm-objdump -l`.
    line = $0
    sub(/^; /, "", line)
    # Project sources only: not the standard library (/rustc/...), not registry crates.
    if (line !~ /^\/rustc\// && line !~ /\/registry\/src\// && (line ~ /\/core\/src\// || line ~ /\/bench-m4\/src\//)) {
        sub(/.*\/core\/src\//, "core/src/", line)
        sub(/.*\/bench-m4\/src\//, "bench-m4/src/", line)
        cursrc = line
    }
    next
}
filen == 1 && /^ *[0-9a-f]+: / {
    n = split($0, f, "\t")
    head = f[1]
    addr = head
    sub(/:.*/, "", addr)
    gsub(/ /, "", addr)
    addr = pad8(addr)
    raw = head
    sub(/^[^:]*:/, "", raw)
    nt = split(raw, tok, " ")
    size = 0
    for (i = 1; i <= nt; i++) size += length(tok[i]) / 2
    mn = (n >= 2) ? f[2] : ""
    ops = (n >= 3) ? f[3] : ""
    sub(/@.*/, "", ops)
    if (prevaddr != "") fall[prevaddr] = addr
    prevaddr = addr
    fn[addr] = fname
    src[addr] = cursrc
    nord++
    ord[nord] = addr
    text[addr] = mn " " ops
    mnem[addr] = mn
    oper[addr] = ops
    if (fname ~ /harness::profile_begin$/) begin_fn = fname
    if (fname ~ /harness::profile_end$/) end_fn = fname
    if (!(fname in entry)) entry[fname] = addr
    next
}

# ---- file 2: the trace ------------------------------------------------------------------
function regs(s,    t, k, n, parts, lo, hi) {
    # Number of registers in a {list}, with ranges (r4-r7, d8-d9).
    t = s
    sub(/^[^{]*\{/, "", t)
    sub(/\}.*/, "", t)
    n = split(t, parts, ",")
    k = 0
    for (i2 = 1; i2 <= n; i2++) {
        if (parts[i2] ~ /-/) {
            lo = parts[i2]; hi = parts[i2]
            sub(/-.*/, "", lo); sub(/.*-/, "", hi)
            gsub(/[^0-9]/, "", lo); gsub(/[^0-9]/, "", hi)
            k += hi - lo + 1
        } else {
            k++
        }
    }
    return k
}

# Class and cycles of the instruction at `a`, given the next PC `nxt`.
function cost(a, nxt,    m, o, taken) {
    m = mnem[a]
    o = oper[a]
    sub(/\.(w|n)$/, "", m)
    taken = (nxt != fall[a])
    cls = "alu"
    cyc = 1
    ls = 0
    if (m ~ /^(b|beq|bne|bcs|bhs|bcc|blo|bmi|bpl|bvs|bvc|bhi|bls|bge|blt|bgt|ble|bal)$/) {
        cls = "branch"; cyc = taken ? 1 + P : 1
    } else if (m ~ /^(bl|blx|bx)/) {
        cls = "branch"; cyc = 1 + P
    } else if (m ~ /^cbn?z$/) {
        cls = "branch"; cyc = taken ? 1 + P : 1
    } else if (m ~ /^tb[bh]/) {
        cls = "branch"; cyc = 2 + P
    } else if (m ~ /^(ldrd|strd)/) {
        cls = "load/store"; cyc = 3
    } else if (m ~ /^(ldr|str)/) {
        cls = "load/store"; ls = 1
        cyc = prev_ls ? 1 : 2
        if (m ~ /^ldr/ && o ~ /^[ \t]*pc,/) { cls = "branch"; cyc = 2 + P; ls = 0 }
    } else if (m ~ /^(ldm|stm|push|pop)/) {
        cls = "load/store"; cyc = 1 + regs(o)
        if (m ~ /^(pop|ldm)/ && o ~ /pc/) cyc += P
    } else if (m ~ /^(vpush|vpop|vldm|vstm)/) {
        cls = "fpu"; cyc = 1 + regs(o)
    } else if (m ~ /^(vldr|vstr)/) {
        cls = "fpu"; cyc = 2
    } else if (m ~ /^(vdiv|vsqrt)/) {
        cls = "fpu"; cyc = 14
    } else if (m ~ /^(vmla|vmls|vnmla|vnmls|vfma|vfms|vfnma|vfnms)/) {
        cls = "fpu"; cyc = 3
    } else if (m ~ /^v/) {
        cls = "fpu"; cyc = 1
    } else if (m ~ /^[su]div/) {
        cls = "divide"; cyc = 12
    } else if (m ~ /^(mul|mla|mls|smull|umull|smlal|umlal|umaal|smul|smla|smls|smmul|smmla|smmls|smuad|smusd)/) {
        cls = "multiply"; cyc = 1
    } else if (m ~ /^(mov|add)/ && o ~ /^[ \t]*pc,/) {
        cls = "branch"; cyc = 1 + P
    }
    prev_ls = ls
    return cyc
}

function retire(a, nxt, counted,    c) {
    c = cost(a, nxt)
    if (!counted) return
    ni[w]++
    nc[w] += c
    ci[w, cls]++
    cc[w, cls] += c
    classes[cls] = 1
    fi[w, fn[a]]++
    fnames[w, fn[a]] = 1
    mi[w, mnem[a]]++
    mnames[w, mnem[a]] = 1
    si[w, src[a]]++
    sc[w, src[a]] += c
    snames[w, src[a]] = 1
    hot[w, a]++
}

filen == 2 {
    pc = $1
    # The previous instruction retires now that its successor is known.
    if (pend != "") retire(pend, pc, pend_counted)
    pend = ""
    if (state == 0) {
        if (pc == begin_pc) { state = 1; w++ }
        next
    }
    if (state == 1) {
        if (fn[pc] == begin_fn) next
        harness = fn[pc]
        state = 2
    }
    # Inside the window.
    if (fn[pc] == end_fn) { state = 0; next }
    pend = pc
    # The harness loop still retires (load/store pipelining state) but is not counted.
    pend_counted = (fn[pc] != harness)
    next
}

# ---- file 3: the program's output (window names in order) -------------------------------
filen == 3 && $1 == "PROFILE" {
    nwin++
    wname[nwin] = $2
    c = $3
    sub(/calls=/, "", c)
    wcalls[nwin] = c + 0
    next
}
filen == 3 { next }

END {
    if (w != nwin) {
        printf "ERROR profile: %d windows traced, %d announced\n", w, nwin
        exit 1
    }
    for (k = 1; k <= w; k++) {
        K = wcalls[k] > 0 ? wcalls[k] : 1
        name = wname[k]
        printf "PROF %s calls=%d instr_x1000=%d cycles_x1000=%d\n", name, K, ni[k] * 1000 / K, nc[k] * 1000 / K
        for (c in classes) if ((k, c) in ci)
            printf "CLASS %s %s instr_x1000=%d cycles_x1000=%d\n", name, c, ci[k, c] * 1000 / K, cc[k, c] * 1000 / K
        for (key in fnames) {
            split(key, kk, SUBSEP)
            if (kk[1] == k) printf "FUNC %s instr_x1000=%d %s\n", name, fi[key] * 1000 / K, kk[2]
        }
        for (key in mnames) {
            split(key, kk, SUBSEP)
            if (kk[1] == k) printf "MNEM %s instr_x1000=%d %s\n", name, mi[key] * 1000 / K, kk[2]
        }
        for (key in snames) {
            split(key, kk, SUBSEP)
            if (kk[1] == k) printf "SRC %s instr_x1000=%d cycles_x1000=%d %s\n", name, si[key] * 1000 / K, sc[key] * 1000 / K, kk[2]
        }
        if (name == annotate) {
            for (i = 1; i <= nord; i++) {
                a = ord[i]
                if ((k, a) in hot) printf "HOT %s %s instr_x1000=%d %s %s | %s\n", name, a, hot[k, a] * 1000 / K, src[a], fn[a], text[a]
            }
        }
    }
}
