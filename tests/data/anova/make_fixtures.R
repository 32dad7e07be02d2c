# Fixtures for tests/validation/test_anova*.cpp, computed independently of stiffid with R 4.2,
# afex 1.2 and car 3.1 (Debian bookworm: apt-get install r-base-core r-cran-afex r-cran-car).
# Run from this folder:  Rscript make_fixtures.R
# Writes, per data set NAME, NAME.csv (long-format input; values rounded to 6 decimals so the CSV
# text is the exact data R analysed) and the answers:
#   rm_effects.csv    afex::aov_ez (type III): df1, df2, F, p (correction "none"), pes, ges,
#                     epsilon_gg / p_gg and epsilon_hf / p_hf (afex's corrected df over the
#                     uncorrected, HF capped at 1 by afex)
#   rm_mauchly.csv    Mauchly's W and p from summary(<afex>$Anova)$sphericity.tests
#   rm_pairwise.csv   paired t-tests on subject means per level (t.test), p.adjust holm/bonferroni
#   mixed_effects.csv classical mixed-model ANOVA: SS from base aov() on the full factorial,
#                     F denominators written out BY HAND from textbook EMS tables (Montgomery,
#                     Design and Analysis of Experiments, ch. 13: restricted and unrestricted
#                     models), Satterthwaite df for quasi-F.
suppressPackageStartupMessages({
  library(afex)
  library(car)
})
options(contrasts = c("contr.sum", "contr.poly"))
g17 <- function(x) ifelse(is.na(x), "", sprintf("%.17g", x))

# Long data with non-spherical within errors (level-specific noise and subject slopes).
make_rm <- function(seed, n_per_group, within, between = NULL) {
  set.seed(seed)
  grid_w <- expand.grid(rev(within), stringsAsFactors = FALSE)[, rev(seq_along(within)), drop = FALSE]
  names(grid_w) <- names(within)
  rows <- list()
  sid <- 0
  groups <- if (is.null(between)) list(NULL) else seq_along(between[[1]])
  for (g in groups) {
    n_g <- if (is.null(g)) n_per_group[1] else n_per_group[g]
    for (s in seq_len(n_g)) {
      sid <- sid + 1
      subj <- rnorm(1, 0, 2)
      slope <- rnorm(ncol(grid_w), 0, 1)
      d <- grid_w
      y <- 10 + subj
      for (f in seq_along(within)) {
        lev <- match(d[[f]], within[[f]])
        y <- y + 0.4 * lev * (f %% 2 + 1) + slope[f] * lev * 0.5 + rnorm(nrow(d), 0, 0.3 * lev)
      }
      if (!is.null(g)) {
        d[[names(between)[1]]] <- between[[1]][g]
        y <- y + 0.8 * g
      }
      d$id <- sprintf("s%02d", sid)
      d$err <- round(y, 6)
      rows[[length(rows) + 1]] <- d
    }
  }
  out <- do.call(rbind, rows)
  out[, c("id", names(between), names(within), "err")]
}

rm_results <- function(name, data, within, between = NULL, pairwise = character(0)) {
  write.csv(data, paste0(name, ".csv"), row.names = FALSE, quote = FALSE)
  data <- read.csv(paste0(name, ".csv"), colClasses = "character")
  data$err <- as.numeric(data$err)
  fit <- suppressMessages(aov_ez("id", "err", data, within = within, between = between,
                                 anova_table = list(correction = "none", es = c("pes", "ges"))))
  none <- fit$anova_table
  gg <- anova(fit, correction = "GG", es = "none")
  hf <- anova(fit, correction = "HF", es = "none")
  eff <- data.frame(dataset = name, effect = rownames(none), df1 = g17(none[["num Df"]]),
                    df2 = g17(none[["den Df"]]), F = g17(none$F), p = g17(none[["Pr(>F)"]]),
                    pes = g17(none$pes), ges = g17(none$ges),
                    epsilon_gg = g17(gg[["num Df"]] / none[["num Df"]]), p_gg = g17(gg[["Pr(>F)"]]),
                    epsilon_hf = g17(hf[["num Df"]] / none[["num Df"]]), p_hf = g17(hf[["Pr(>F)"]]))
  sph <- suppressWarnings(summary(fit$Anova, multivariate = FALSE)$sphericity.tests)
  mau <- if (is.null(sph) || nrow(sph) == 0) NULL else
    data.frame(dataset = name, effect = rownames(sph), W = g17(sph[, "Test statistic"]),
               p = g17(sph[, "p-value"]))
  pw <- NULL
  for (f in pairwise) {
    m <- aggregate(data$err, by = list(id = data$id, level = data[[f]]), FUN = mean)
    levels_f <- unique(data[[f]])
    pairs <- NULL
    for (i in seq_along(levels_f)) for (j in seq_along(levels_f)) if (i < j) {
      a <- m$x[m$level == levels_f[i]][order(m$id[m$level == levels_f[i]])]
      b <- m$x[m$level == levels_f[j]][order(m$id[m$level == levels_f[j]])]
      tt <- t.test(a, b, paired = TRUE)
      pairs <- rbind(pairs, data.frame(dataset = name, factor = f, level1 = levels_f[i],
                                       level2 = levels_f[j], mean_diff = unname(tt$estimate),
                                       se = unname(tt$stderr), t = unname(tt$statistic),
                                       df = unname(tt$parameter), p = tt$p.value))
    }
    pairs$p_holm <- p.adjust(pairs$p, "holm")
    pairs$p_bonferroni <- p.adjust(pairs$p, "bonferroni")
    for (k in c("mean_diff", "se", "t", "df", "p", "p_holm", "p_bonferroni")) pairs[[k]] <- g17(pairs[[k]])
    pw <- rbind(pw, pairs)
  }
  list(effects = eff, mauchly = mau, pairwise = pw)
}

sets <- list(
  rm_results("oneway", make_rm(11, 10, list(method = c("m1", "m2", "m3", "m4"))), "method",
             pairwise = "method"),
  rm_results("twoway", make_rm(12, 12, list(method = c("m1", "m2", "m3"), noise = c("n1", "n2"))),
             c("method", "noise"), pairwise = c("method", "noise")),
  rm_results("threeway", make_rm(13, 10, list(a = c("a1", "a2", "a3"), b = c("b1", "b2"),
                                             c = c("c1", "c2", "c3"))), c("a", "b", "c")),
  rm_results("mixed_balanced", make_rm(14, c(7, 7), list(method = c("m1", "m2", "m3"),
                                                        noise = c("n1", "n2")),
                                       list(group = c("g1", "g2"))),
             c("method", "noise"), "group"),
  rm_results("mixed_unbalanced", make_rm(15, c(5, 7, 6), list(method = c("m1", "m2", "m3", "m4")),
                                         list(group = c("g1", "g2", "g3"))),
             "method", "group", pairwise = "method")
)

# Several rows per subject x cell: afex averages them (fun_aggregate = mean); so must stiffid.
dup <- make_rm(16, 8, list(method = c("m1", "m2", "m3")))
set.seed(17)
extra <- dup[sample(nrow(dup), 6), ]
extra$err <- round(extra$err + rnorm(6, 0, 1), 6)
dup <- rbind(dup, extra)
sets[[length(sets) + 1]] <- rm_results("duplicates", dup, "method")

write.csv(do.call(rbind, lapply(sets, `[[`, "effects")), "rm_effects.csv", row.names = FALSE,
          quote = FALSE)
write.csv(do.call(rbind, lapply(sets, `[[`, "mauchly")), "rm_mauchly.csv", row.names = FALSE,
          quote = FALSE)
write.csv(do.call(rbind, lapply(sets, `[[`, "pairwise")), "rm_pairwise.csv", row.names = FALSE,
          quote = FALSE)

# ---- Classical mixed model with random factors --------------------------------------------------
make_crossed <- function(seed, levels, n) {
  set.seed(seed)
  d <- expand.grid(c(rev(levels), list(rep = seq_len(n))), stringsAsFactors = FALSE)
  d <- d[, c(rev(seq_along(levels)), length(levels) + 1)]
  names(d) <- c(names(levels), "rep")
  y <- rep(20, nrow(d))
  for (f in names(levels)) {
    eff <- rnorm(length(levels[[f]]), 0, 1.5)
    y <- y + eff[match(d[[f]], levels[[f]])]
  }
  # random interactions with the first (fixed) factor
  key <- paste(d[[1]], d[[2]])
  ie <- rnorm(length(unique(key)), 0, 1)
  y <- y + ie[match(key, unique(key))] + rnorm(nrow(d), 0, 1)
  d$err <- round(y, 6)
  d[, c(names(levels), "err")]
}

ms_table <- function(data, factors) {
  fit <- aov(as.formula(paste("err ~", paste(factors, collapse = "*"))), data = data)
  s <- summary(fit)[[1]]
  rn <- trimws(rownames(s))
  rn <- gsub(" ", "", rn)
  list(ms = setNames(s[["Mean Sq"]], rn), df = setNames(s[["Df"]], rn),
       ss = setNames(s[["Sum Sq"]], rn))
}

# den: named vector of coefficients over mean squares ("Residuals" = within-cell error).
test_row <- function(name, model, effect, type, den, t) {
  ms <- t$ms[effect]
  d <- sum(den * t$ms[names(den)])
  quasi <- length(den) > 1
  df2 <- if (quasi) d^2 / sum((den * t$ms[names(den)])^2 / t$df[names(den)]) else t$df[names(den)]
  f <- ms / d
  p <- pf(f, t$df[effect], df2, lower.tail = FALSE)
  data.frame(dataset = name, model = model, effect = effect, type = type,
             df1 = g17(t$df[effect]), df2 = g17(df2), F = g17(f), p = g17(p),
             ss = g17(t$ss[effect]), quasi = ifelse(quasi, "true", "false"))
}

mixed <- NULL
# (1) method fixed (a = 3), kprofile random (b = 3), cprofile random (c = 4), n = 2 per cell.
r3 <- make_crossed(21, list(method = c("m1", "m2", "m3"), kprofile = c("k1", "k2", "k3"),
                            cprofile = c("c1", "c2", "c3", "c4")), 2)
write.csv(r3, "random3.csv", row.names = FALSE, quote = FALSE)
r3 <- read.csv("random3.csv", colClasses = c("character", "character", "character", "numeric"))
t3 <- ms_table(r3, c("method", "kprofile", "cprofile"))
A <- "method"; B <- "kprofile"; C <- "cprofile"
AB <- "method:kprofile"; AC <- "method:cprofile"; BC <- "kprofile:cprofile"
ABC <- "method:kprofile:cprofile"; E <- "Residuals"
unres <- list(
  list(A, "fixed", setNames(c(1, 1, -1), c(AB, AC, ABC))),
  list(B, "random", setNames(c(1, 1, -1), c(AB, BC, ABC))),
  list(C, "random", setNames(c(1, 1, -1), c(AC, BC, ABC))),
  list(AB, "random", setNames(1, ABC)), list(AC, "random", setNames(1, ABC)),
  list(BC, "random", setNames(1, ABC)), list(ABC, "random", setNames(1, E)))
res <- list(
  list(A, "fixed", setNames(c(1, 1, -1), c(AB, AC, ABC))),
  list(B, "random", setNames(1, BC)), list(C, "random", setNames(1, BC)),
  list(AB, "random", setNames(1, ABC)), list(AC, "random", setNames(1, ABC)),
  list(BC, "random", setNames(1, E)), list(ABC, "random", setNames(1, E)))
for (r in unres) mixed <- rbind(mixed, test_row("random3", "unrestricted", r[[1]], r[[2]], r[[3]], t3))
for (r in res) mixed <- rbind(mixed, test_row("random3", "restricted", r[[1]], r[[2]], r[[3]], t3))

# (2) method fixed (3), kprofile random (4), noise fixed (2), one observation per cell: the
# three-way interaction is the residual (unrestricted model).
r1 <- make_crossed(22, list(method = c("m1", "m2", "m3"), kprofile = c("k1", "k2", "k3", "k4"),
                            noise = c("n1", "n2")), 1)
write.csv(r1, "random_n1.csv", row.names = FALSE, quote = FALSE)
r1 <- read.csv("random_n1.csv", colClasses = c("character", "character", "character", "numeric"))
t1 <- ms_table(r1, c("method", "kprofile", "noise"))
names(t1$ms)[names(t1$ms) == "Residuals"] <- "method:kprofile:noise"
names(t1$df)[names(t1$df) == "Residuals"] <- "method:kprofile:noise"
names(t1$ss)[names(t1$ss) == "Residuals"] <- "method:kprofile:noise"
R <- "method:kprofile:noise"
n1 <- list(
  list("method", "fixed", setNames(1, "method:kprofile")),
  list("kprofile", "random", setNames(c(1, 1, -1), c("method:kprofile", "kprofile:noise", R))),
  list("noise", "fixed", setNames(1, "kprofile:noise")),
  list("method:kprofile", "random", setNames(1, R)), list("method:noise", "fixed", setNames(1, R)),
  list("kprofile:noise", "random", setNames(1, R)))
for (r in n1) mixed <- rbind(mixed, test_row("random_n1", "unrestricted", r[[1]], r[[2]], r[[3]], t1))
write.csv(mixed, "mixed_effects.csv", row.names = FALSE, quote = FALSE)
cat("fixtures written\n")
