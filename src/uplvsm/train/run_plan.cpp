#include "uplvsm/train/run_plan.h"

#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/cpu_isa.h"
#include "uplvsm/train/memory_estimate.h"
#include "uplvsm/train/tokenizer_start.h"

namespace uplvsm::train {

namespace {

std::string line(const std::string& name, const std::string& value) { return fmt::format("{:<13} {}", name, value); }

std::string global_batch_line(const TrainingConfig& t, const BatchPlan& b) {
  return line("global batch", fmt::format("{} scenes per update = {} per micro-batch x {} accumulated x {} rank(s){}; "
                                          "{} views each ({} inputs, {} targets)",
                                          b.global(), b.per_micro_batch, b.accumulation, b.ranks,
                                          t.global_batch_size > 0 ? " (training.global_batch_size)" : "", t.num_views,
                                          t.num_input_views, t.num_target_views));
}

std::string schedule_line(const TrainingConfig& t) {
  const std::string clip = t.grad_clip_norm > 0 ? fmt::format("clip {:g}, updates skipped above {:g} x clip",
                                                              t.grad_clip_norm, t.allowed_gradnorm_factor)
                                                : "no clipping (grad_clip_norm 0)";
  return line("schedule", fmt::format("{} updates; AdamW lr {:g} (betas {:g}/{:g}, weight decay {:g}), linear warmup "
                                      "{} then cosine to 0; {}",
                                      t.train_steps, t.lr, t.beta1, t.beta2, t.weight_decay, t.warmup, clip));
}

std::string precision_line(const TrainingConfig& t, const std::string& device) {
  const bool cuda = device.rfind("cuda", 0) == 0;
  std::string amp = t.amp == Amp::Bf16 ? "bf16 autocast, fp32 master weights" : "fp32";
  if (t.amp == Amp::Bf16 && !bf16_autocast_pays(cuda ? torch::Device(torch::kCUDA) : torch::Device(torch::kCPU)))
    amp = fmt::format("fp32 (bf16 asked for: this CPU has no native bf16 dot product, {})", isa_name(active_isa()));
  const std::string tf32 = fmt::format("TF32 {}{}", t.tf32 ? "on" : "off", cuda ? "" : " (CUDA only: no effect here)");
  return line("precision", fmt::format("{}; {}; on {}", amp, tf32, device));
}

std::string loss_line(const TrainingConfig& t, const std::string& vgg) {
  std::string s = fmt::format("{:g} x MSE", t.l2_loss_weight);
  if (t.perceptual_loss_weight > 0)
    s += fmt::format(" + {:g} x perceptual (VGG19 {})", t.perceptual_loss_weight,
                     vgg.empty() ? "MISSING: the run refuses to start" : "from " + vgg);
  if (t.gradient_difference_weight > 0)
    s += fmt::format(" + {:g} x gradient difference (not in the paper)", t.gradient_difference_weight);
  return line("loss", s);
}

std::string data_line(const RunPlan& p) {
  const auto& t = p.config.training;
  if (p.data_root.empty()) return line("data", "not given (--data): scene count and epochs unknown");
  std::string where = p.data_root + (t.subset.empty() ? "" : ", subset " + t.subset);
  if (!p.scenes) return line("data", where);
  const double samples = static_cast<double>(t.train_steps) * static_cast<double>(p.batch.global());
  if (p.split_scenes && *p.split_scenes > *p.scenes)
    where += fmt::format(" (the first {} of {})", *p.scenes, *p.split_scenes);
  return line("data", fmt::format("{} scenes of {}; {:.0f} samples in all = {:.1f} epochs", *p.scenes, where, samples,
                                  *p.scenes > 0 ? samples / static_cast<double>(*p.scenes) : 0.0));
}

std::string shuffle_line(const TrainingConfig& t) {
  return line("shuffling", t.chunks_per_shuffle == 0
                               ? std::string("the whole split, reshuffled each epoch (the official DistributedSampler)")
                               : fmt::format("{} chunk(s) at a time, scenes shuffled within them (not the official "
                                             "whole-split order; training.chunks_per_shuffle)",
                                             t.chunks_per_shuffle));
}

std::string views_line(const RunPlan& p) {
  const auto& t = p.config.training;
  const bool ordered = p.ordered_views.value_or(t.view_sampler != "unordered");
  std::string s = ordered ? fmt::format("ordered: context views {}..{} frames apart{}", t.min_frame_dist,
                                        t.max_frame_dist, p.ordered_views ? "" : " (unless the dataset says unordered)")
                          : "unordered: any distinct frames";
  s += t.pose_noise_std > 0 ? fmt::format("; pose noise N(0, {:g}^2) on the told cameras", t.pose_noise_std)
                            : "; no pose noise";
  return line("views", s + "; target poses " + uplvsm::to_string(t.target_poses));
}

}  // namespace

std::vector<std::string> describe_run_plan(const RunPlan& p) {
  const auto& c = p.config;
  const auto& t = c.training;
  const auto memory = train::training_memory(c);
  return {line("model", fmt::format("{} ({}, {} parameters){}", c.name, to_string(c.model.variant), memory.parameters,
                                    p.init.empty() ? "" : ", starting from " + p.init)),
          line("tokenizer", describe_tokenizer_start(c, p.init, p.resuming)),
          global_batch_line(t, p.batch),
          schedule_line(t),
          precision_line(t, p.device),
          loss_line(t, p.perceptual_weights),
          data_line(p),
          shuffle_line(t),
          views_line(p),
          line("memory", fmt::format("at least {:.1f} GiB per process (weights, gradients, AdamW state and the "
                                     "activations of one micro-batch)",
                                     memory.total() / (1024.0 * 1024.0 * 1024.0)))};
}

}  // namespace uplvsm::train
