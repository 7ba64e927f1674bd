// A video between two photos with any UP-LVSM checkpoint (the authors' .pt/.safetensors or a uplvsm run):
//   render_two_photos CHECKPOINT A.jpg B.jpg OUT.mp4
#include <uplvsm/uplvsm.h>

#include <iostream>

int main(int argc, char** argv) {
  if (argc != 5) {
    std::cerr << "usage: render_two_photos CHECKPOINT A.jpg B.jpg OUT.mp4\n";
    return 2;
  }
  try {
    uplvsm::init_runtime();  // threads and allocator as the uplvsm binary sets them
    uplvsm::Config config;
    auto model = uplvsm::model::require_uplvsm(uplvsm::model::load_model(argv[1], torch::kCPU, &config), argv[1]);
    uplvsm::data::PreprocessOptions size{int(config.model.image_size), int(config.model.patch_size), true};
    auto photos = uplvsm::data::load_photos({argv[2], argv[3]}, /*fov_degrees=*/60.0, size);
    auto video = uplvsm::render::render_interpolation(model, photos.images, photos.fxfycxcy, /*num_frames=*/24);
    std::vector<torch::Tensor> frames;
    for (const auto& frame : video.frames.unbind(0)) frames.push_back(uplvsm::io::to_u8_hwc(frame));
    uplvsm::io::write_mp4(argv[4], frames, /*fps=*/12.0);
    std::cout << "wrote " << frames.size() << " frames to " << argv[4] << "\n";
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
